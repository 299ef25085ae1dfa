#include "stf/pack.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>

#include "stf/sh.h"
#include "stf/tilt.h"

namespace stf {

namespace {

constexpr char kMagic[8] = {'S', 'T', 'F', 'P', 'A', 'C', 'K', '1'};
constexpr std::size_t kHeaderBytes = 32;
constexpr std::uintmax_t kMaxPackBytes = std::uintmax_t(1) << 32;  // record sizes are 32-bit

std::uint64_t fnv1a(const std::uint8_t* p, std::size_t n) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (std::size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 0x100000001b3ull;
  return h;
}

std::size_t pad4(std::size_t n) { return (n + 3) & ~std::size_t(3); }

// Record flags: bit 0 hemispherical lobes, bits 1-2 the alpha blend (the widest where bins
// differ), bit 3 a turn per bin follows the tilts, bit 4 a blend width per bin follows those,
// bit 5 lifted lobes.
constexpr std::uint32_t kTurnsFlag = 8;
constexpr std::uint32_t kBlendWidthsFlag = 16;
constexpr std::uint32_t kLiftedFlag = 32;

// Float32 values per lobe: weight, kappa and the mean's polar and azimuthal angles (float32
// angles place a mean to ~1e-7 rad, below the width of any lobe a table resolves).
constexpr std::size_t kFloatsPerLobe = 4;

std::size_t parameter_count(int kind, std::uint32_t bins, std::uint32_t size, std::int32_t degree) {
  if (kind == 0) return std::size_t(bins) * size * kFloatsPerLobe;
  std::size_t count = std::size_t(size + 1) * (size + 1);
  return degree >= 0 ? std::size_t(degree + 1) * count : std::size_t(bins) * count;
}

// Little-endian writer.
struct Writer {
  std::vector<std::uint8_t> out;
  template <typename T>
  void put(T v) {
    std::uint8_t b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));  // the supported targets are little-endian (checked below)
    out.insert(out.end(), b, b + sizeof(T));
  }
  void bytes(const void* p, std::size_t n) {
    if (n == 0) return;
    auto* c = static_cast<const std::uint8_t*>(p);
    out.insert(out.end(), c, c + n);
  }
  void align4() {
    while (out.size() % 4) out.push_back(0);
  }
};

// Bounds-checked little-endian reader: every read past the end fails instead of reading.
struct Reader {
  const std::uint8_t* p;
  std::size_t size, at = 0;
  bool ok = true;
  template <typename T>
  T get() {
    T v{};
    if (!ok || size - at < sizeof(T)) {
      ok = false;
      return v;
    }
    std::memcpy(&v, p + at, sizeof(T));
    at += sizeof(T);
    return v;
  }
  bool skip(std::size_t n) {
    if (!ok || size - at < n) return ok = false;
    at += n;
    return true;
  }
};

bool little_endian() {
  std::uint32_t one = 1;
  std::uint8_t first;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

}  // namespace

std::int64_t record_bytes(const StfModel& m, std::size_t name_bytes) {
  const int kind = m.kind == ModelKind::kVmf ? 0 : 1;
  const std::uint32_t size = kind == 0 ? std::uint32_t(m.lobes) : std::uint32_t(m.band_limit);
  const std::size_t per_bin = m.alpha_turn.empty() ? 8 : 12;  // probability, tilt, and turn when it turns
  const std::size_t widths = m.alpha_blend_width.empty() ? 0 : pad4(std::size_t(m.bins()));
  std::size_t n = 4 + 4 + pad4(name_bytes) + 6 * 4 + 8 * 8 + per_bin * std::size_t(m.bins()) + pad4(std::size_t(m.bins())) + widths;
  return std::int64_t(n + 4 * parameter_count(kind, std::uint32_t(m.bins()), size, m.alpha_degree));
}

std::vector<std::uint8_t> write_pack(const std::vector<PackEntry>& entries) {
  if (std::string why = pack_entries_error(entries); !why.empty()) throw std::invalid_argument(why);
  Writer payload;
  for (const PackEntry& e : entries) {
    const StfModel& m = e.model;
    const int kind = m.kind == ModelKind::kVmf ? 0 : 1;
    const std::uint32_t bins = std::uint32_t(m.bins());
    const std::uint32_t size = kind == 0 ? std::uint32_t(m.lobes) : std::uint32_t(m.band_limit);
    payload.put(std::uint32_t(record_bytes(m, e.name.size())));
    payload.put(std::uint32_t(e.name.size()));
    payload.bytes(e.name.data(), e.name.size());
    payload.align4();
    for (std::uint32_t v : {std::uint32_t(kind), bins, size, std::uint32_t(m.sh_nz)}) payload.put(v);
    payload.put(std::int32_t(m.alpha_degree));
    payload.put(std::uint32_t((m.hemispherical ? 1 : 0) | (std::uint32_t(m.alpha_blend) << 1) |
                              (m.alpha_turn.empty() ? 0 : kTurnsFlag) |
                              (m.alpha_blend_width.empty() ? 0 : kBlendWidthsFlag) | (m.lifted ? kLiftedFlag : 0)));  // flags
    for (double v : {m.tau, m.albedo, m.g, m.escape_probability, m.absorbed_fraction, m.truncated_fraction,
                     m.uncollided_fraction, m.once_fraction})
      payload.put(v);
    for (double p : m.alpha_probability) payload.put(float(p));
    for (BinStatus s : m.status) payload.put(std::uint8_t(s));
    payload.align4();
    for (int b = 0; b < m.bins(); ++b) payload.put(float(m.tilt(b)));
    for (double r : m.alpha_turn) payload.put(float(r));
    for (int h : m.alpha_blend_width) payload.put(std::uint8_t(h));
    payload.align4();
    if (kind == 0) {
      for (const VmfLobe& l : m.vmf)
        for (double v : {l.weight, l.kappa, std::atan2(std::hypot(l.mean.x, l.mean.y), l.mean.z), std::atan2(l.mean.y, l.mean.x)})
          payload.put(float(v));
    } else {
      for (double v : m.alpha_degree >= 0 ? m.sh_chebyshev : m.sh) payload.put(float(v));
    }
  }
  Writer pack;
  for (char c : kMagic) pack.put(std::uint8_t(c));
  pack.put(kPackVersion);
  pack.put(std::uint32_t(entries.size()));
  pack.put(std::uint64_t(payload.out.size()));
  pack.put(fnv1a(payload.out.data(), payload.out.size()));
  pack.bytes(payload.out.data(), payload.out.size());
  return pack.out;
}

namespace {

bool fail(std::string& error, const std::string& why) {
  error = why;
  return false;
}

bool finite(double v) { return std::isfinite(v); }

// Names are text for every reader (Python's str among them): well-formed UTF-8, shortest forms,
// no surrogates, no NUL.
bool valid_utf8(const std::string& s) {
  for (std::size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    const int n = c < 0x80 ? 0 : (c & 0xe0) == 0xc0 ? 1 : (c & 0xf0) == 0xe0 ? 2 : (c & 0xf8) == 0xf0 ? 3 : -1;
    if (c == 0 || n < 0 || (n > 0 && i + std::size_t(n) >= s.size())) return false;
    std::uint32_t code = n == 0 ? c : c & (0x3f >> n);
    for (int k = 1; k <= n; ++k) {
      const auto d = static_cast<unsigned char>(s[i + std::size_t(k)]);
      if ((d & 0xc0) != 0x80) return false;
      code = (code << 6) | (d & 0x3f);
    }
    const std::uint32_t least[] = {0, 0x80, 0x800, 0x10000};
    if (code < least[n] || code > 0x10ffff || (code >= 0xd800 && code <= 0xdfff)) return false;
    i += std::size_t(n) + 1;
  }
  return true;
}

// A record's fixed fields, before its numbers.
struct RecordHeader {
  std::uint32_t record = 0;  // bytes, from its start
  std::uint32_t kind = 0, bins = 0, size = 0, nz = 0, flags = 0;
  std::int32_t degree = -1;
  bool turns() const { return flags & kTurnsFlag; }
  bool widths() const { return flags & kBlendWidthsFlag; }
};

// The name and the fixed fields, their ranges checked, and the record's size against them.
bool read_header(Reader& r, PackEntry& e, RecordHeader& h, std::string& error) {
  const std::size_t start = r.at;
  const std::uint32_t record = h.record = r.get<std::uint32_t>(), name_bytes = r.get<std::uint32_t>();
  if (!r.ok || record > r.size - start || record < 8 || name_bytes > record - 8) return fail(error, "truncated model record");
  e.name.assign(reinterpret_cast<const char*>(r.p + r.at), name_bytes);
  if (!valid_utf8(e.name)) return fail(error, "model name is not UTF-8 text");
  r.skip(pad4(name_bytes));
  h.kind = r.get<std::uint32_t>(), h.bins = r.get<std::uint32_t>();
  h.size = r.get<std::uint32_t>(), h.nz = r.get<std::uint32_t>();
  h.degree = r.get<std::int32_t>();
  h.flags = r.get<std::uint32_t>();
  if (!r.ok) return fail(error, "truncated model record");
  if (h.kind > 1) return fail(error, "unknown model kind " + std::to_string(h.kind));
  if (std::string why = model_size_error(h.kind == 1, h.bins, h.size, h.nz, h.degree); !why.empty())
    return fail(error, why);
  if (h.flags > (kLiftedFlag | kBlendWidthsFlag | kTurnsFlag | 7u)) return fail(error, "unknown model flags");
  const std::size_t per_bin = h.turns() ? 12 : 8;  // probability and tilt, and the turn
  if (std::int64_t(record) != std::int64_t(4 + 4 + pad4(name_bytes) + 6 * 4 + 8 * 8 + per_bin * std::size_t(h.bins) +
                                            pad4(h.bins) + (h.widths() ? pad4(h.bins) : 0) +
                                            4 * parameter_count(int(h.kind), h.bins, h.size, h.kind == 1 ? h.degree : -1)))
    return fail(error, "model record size does not match its contents");
  return true;
}

// The medium and the outcome probabilities.
bool read_medium(Reader& r, StfModel& m, std::string& error) {
  m.tau = r.get<double>(), m.albedo = r.get<double>(), m.g = r.get<double>();
  m.escape_probability = r.get<double>(), m.absorbed_fraction = r.get<double>(), m.truncated_fraction = r.get<double>();
  m.uncollided_fraction = r.get<double>();
  m.once_fraction = r.get<double>();
  if (!(m.once_fraction >= 0 && m.once_fraction <= 1)) return fail(error, "once-scattered fraction out of range");
  if (!(m.absorbed_fraction >= 0 && m.absorbed_fraction <= 1 && m.truncated_fraction >= 0 && m.truncated_fraction <= 1))
    return fail(error, "absorbed or truncated fraction out of range [0, 1]");
  if (!(m.tau > 0 && m.tau <= kMaxModelTau && m.albedo >= 0 && m.albedo <= 1 && m.g > -1 && m.g < 1 &&
        m.escape_probability >= 0 && m.escape_probability <= 1 && finite(m.absorbed_fraction) &&
        finite(m.truncated_fraction)))
    return fail(error, "medium parameters out of range");
  return true;
}

// The alpha marginal, the bins' status, tilts, turns and blend widths.
bool read_alpha(Reader& r, const RecordHeader& h, StfModel& m, std::string& error) {
  double total = 0;
  for (std::uint32_t b = 0; b < h.bins; ++b) {
    double p = r.get<float>();
    if (!(p >= 0 && finite(p))) return fail(error, "alpha probability is negative or not finite");
    m.alpha_probability.push_back(p);
    total += p;
  }
  if (total > 0 && std::abs(total - 1) > 1e-4) return fail(error, "alpha probabilities do not sum to 1");
  // The uncollided escapes are part of alpha bin 0's probability (stored as float32).
  if (!(m.uncollided_fraction >= 0 && m.uncollided_fraction <= m.alpha_probability[0] * (1 + 1e-6) + 1e-12))
    return fail(error, "uncollided fraction out of range");
  m.uncollided_fraction = std::min(m.uncollided_fraction, m.alpha_probability[0]);
  for (std::uint32_t b = 0; b <= h.bins; ++b) m.alpha_edges.push_back(kPi * b / h.bins);
  for (std::uint32_t b = 0; b < h.bins; ++b) {
    std::uint8_t s = r.get<std::uint8_t>();
    if (s > 2) return fail(error, "bin status out of range");
    m.status.push_back(BinStatus(s));
  }
  r.skip(pad4(h.bins) - h.bins);
  for (std::uint32_t b = 0; b < h.bins; ++b) {
    const double t = r.get<float>();
    if (!(std::abs(t) <= kMaxTilt)) return fail(error, "alpha tilt out of range");
    m.alpha_tilt.push_back(t);
  }
  for (std::uint32_t b = 0; b < h.bins && h.turns(); ++b) {
    const double turn = r.get<float>();
    if (!(std::abs(turn) <= StfModel::kMaxTurn)) return fail(error, "alpha turn out of range");
    m.alpha_turn.push_back(turn);
  }
  for (std::uint32_t b = 0; b < h.bins && h.widths(); ++b) {
    const int width = r.get<std::uint8_t>();
    if (width > m.alpha_blend) return fail(error, "alpha blend width out of range");
    m.alpha_blend_width.push_back(width);
  }
  if (h.widths()) r.skip(pad4(h.bins) - h.bins);
  return true;
}

// vMF lobes: weight, kappa and the mean's angles; each bin's weights renormalised.
bool read_lobes(Reader& r, const RecordHeader& h, StfModel& m, std::string& error) {
  m.lobes = int(h.size);
  for (std::size_t i = 0; i < std::size_t(h.bins) * h.size; ++i) {
    const double w = r.get<float>(), k = r.get<float>(), theta = r.get<float>(), phi = r.get<float>();
    if (!(theta >= -1e-6 && theta <= kPi + 1e-6 && std::abs(phi) <= kPi + 1e-6))
      return fail(error, "vMF lobe parameters out of range");
    const double x = std::sin(theta) * std::cos(phi), y = std::sin(theta) * std::sin(phi), z = std::cos(theta);
    const double len = std::sqrt(x * x + y * y + z * z);
    if (!(w >= 0 && finite(w) && k >= 0 && k <= 1e9 && finite(len) && len > 0.5 && len < 2))
      return fail(error, "vMF lobe parameters out of range");
    m.vmf.push_back({w, k, {x / len, y / len, z / len}});
  }
  for (std::uint32_t b = 0; b < h.bins; ++b) {
    double s = 0;
    for (std::uint32_t k = 0; k < h.size; ++k) s += m.vmf[b * h.size + k].weight;
    if (std::abs(s - 1) > 1e-4) return fail(error, "vMF weights of a bin do not sum to 1");
    for (std::uint32_t k = 0; k < h.size; ++k) m.vmf[b * h.size + k].weight /= s;
  }
  m.rebuild_lobe_norms();
  return true;
}

// SH coefficients per bin, or a Chebyshev series across alpha evaluated at the bin centres.
bool read_sh(Reader& r, const RecordHeader& h, StfModel& m, std::string& error) {
  m.band_limit = int(h.size);
  m.sh_nz = int(h.nz);
  m.alpha_degree = h.degree;
  std::vector<double>& target = h.degree >= 0 ? m.sh_chebyshev : m.sh;
  for (std::size_t i = 0; i < parameter_count(1, h.bins, h.size, h.degree); ++i) {
    double v = r.get<float>();
    if (!(std::abs(v) <= 1e6)) return fail(error, "SH coefficient out of range");
    target.push_back(v);
  }
  if (h.degree >= 0) {
    const int count = sh_count(int(h.size));
    m.sh.assign(std::size_t(h.bins) * count, 0.0);
    for (std::uint32_t b = 0; b < h.bins; ++b) {
      double x = std::cos(kPi * (b + 0.5) / h.bins);
      for (int j = 0; j <= h.degree; ++j) {
        double t = std::cos(j * std::acos(x));
        for (int i = 0; i < count; ++i) m.sh[std::size_t(b) * count + i] += t * m.sh_chebyshev[std::size_t(j) * count + i];
      }
    }
  }
  m.rebuild_sh_tables();
  for (float v : m.sh_table)
    if (!std::isfinite(v)) return fail(error, "SH density not finite");
  return true;
}

// One model record; `r` is positioned at its start.
bool read_record(Reader& r, PackEntry& e, std::string& error) {
  const std::size_t start = r.at;
  RecordHeader h;
  if (!read_header(r, e, h, error)) return false;
  StfModel& m = e.model;
  m.kind = h.kind == 0 ? ModelKind::kVmf : ModelKind::kSh;
  m.hemispherical = h.kind == 0 && (h.flags & 1);
  m.lifted = h.kind == 0 && (h.flags & kLiftedFlag);
  m.alpha_blend = int((h.flags >> 1) & 3u);
  if (!read_medium(r, m, error) || !read_alpha(r, h, m, error)) return false;
  if (!(h.kind == 0 ? read_lobes(r, h, m, error) : read_sh(r, h, m, error))) return false;
  if (!r.ok || r.at != start + h.record) return fail(error, "model record size does not match its contents");
  if (std::string why = draw_error(m); !why.empty()) return fail(error, why);
  return true;
}

}  // namespace

bool read_pack(const std::uint8_t* data, std::size_t size, std::vector<PackEntry>& entries, std::string& error) {
  entries.clear();
  if (!little_endian()) return fail(error, "stf packs need a little-endian machine");
  if (size < kHeaderBytes) return fail(error, "not an stf pack (too short)");
  if (std::memcmp(data, kMagic, 8) != 0) return fail(error, "not an stf pack (bad magic)");
  Reader r{data, size, 8};
  const std::uint32_t version = r.get<std::uint32_t>(), count = r.get<std::uint32_t>();
  const std::uint64_t payload = r.get<std::uint64_t>(), checksum = r.get<std::uint64_t>();
  if (version != kPackVersion)
    return fail(error, "pack version " + std::to_string(version) + (version < kPackVersion ? " is older" : " is newer") +
                           " than this library reads (" + std::to_string(kPackVersion) +
                           "): build the pack again with this stf (stf pack, stf build), fitting its tables again (stf fit)");
  if (payload != size - kHeaderBytes) return fail(error, "pack size does not match its header (truncated?)");
  if (fnv1a(data + kHeaderBytes, payload) != checksum) return fail(error, "pack checksum mismatch (corrupted)");
  if (count > payload / 100 + 1) return fail(error, "model count out of range");
  for (std::uint32_t i = 0; i < count; ++i) {
    PackEntry e;
    if (!read_record(r, e, error)) {
      entries.clear();
      error = "model " + std::to_string(i) + ": " + error;
      return false;
    }
    entries.push_back(std::move(e));
  }
  if (r.at != size) {
    entries.clear();
    return fail(error, "trailing bytes after the last model");
  }
  return true;
}

std::string pack_entry_error(const PackEntry& entry) {
  const std::vector<std::uint8_t> bytes = write_pack({entry});
  std::vector<PackEntry> back;
  std::string error;
  if (read_pack(bytes.data(), bytes.size(), back, error)) return "";
  return error.rfind("model 0: ", 0) == 0 ? error.substr(9) : error;
}

bool read_pack_file(const std::string& path, std::vector<PackEntry>& entries, std::string& error) {
  if (path.find('\0') != std::string::npos) return fail(error, "a file name holding a NUL byte");
  std::error_code code;
  if (!std::filesystem::is_regular_file(path, code)) return fail(error, "cannot open " + path + ": not a regular file");
  const std::uintmax_t size = std::filesystem::file_size(path, code);
  if (code || size > kMaxPackBytes) return fail(error, "cannot open " + path + ": larger than a pack can be (4 GiB)");
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail(error, "cannot open " + path);
  std::vector<std::uint8_t> data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return read_pack(data.data(), data.size(), entries, error);
}

}  // namespace stf
