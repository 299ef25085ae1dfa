#include "stf/core/import.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string_view>

namespace stf {

namespace {

std::string whole_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path + ": " + std::strerror(errno));
  std::ostringstream bytes;
  bytes << in.rdbuf();
  if (in.bad()) throw std::runtime_error("cannot read " + path + ": " + std::strerror(errno));
  return std::move(bytes).str();
}

// The value of `key` in a .npy header (a Python dict literal), up to the next ',' or ')' (a
// tuple's end included).
std::string npy_field(const std::string& header, const std::string& key) {
  const std::size_t at = header.find("'" + key + "'");
  if (at == std::string::npos) return "";
  std::size_t from = header.find(':', at);
  if (from == std::string::npos) return "";
  from = header.find_first_not_of(' ', from + 1);
  if (from == std::string::npos) return "";
  const std::size_t to = header[from] == '(' ? header.find(')', from) + 1 : header.find_first_of(",}", from);
  return header.substr(from, to - from);
}

std::string printable(std::string_view text);
void check_total(const std::vector<double>& counts, const std::string& path);

template <typename T>
void widen(const char* data, std::size_t count, std::vector<double>& out) {
  for (std::size_t i = 0; i < count; ++i) {
    T v;
    std::memcpy(&v, data + i * sizeof(T), sizeof(T));
    out[i] = double(v);
  }
}

}  // namespace

std::vector<double> read_npy_counts(const std::string& path, int alpha_bins, std::int64_t cells) {
  const std::string bytes = whole_file(path);
  auto bad = [&](const std::string& why) { return std::runtime_error(path + ": " + why); };
  if (bytes.size() < 10 || bytes.compare(0, 6, "\x93NUMPY") != 0) throw bad("not a .npy file");
  const int major = static_cast<unsigned char>(bytes[6]);
  const std::size_t length_bytes = major == 1 ? 2 : 4;
  if (major < 1 || major > 3 || bytes.size() < 8 + length_bytes) throw bad("unsupported .npy version " + std::to_string(major));
  std::size_t header_length = 0;
  for (std::size_t i = 0; i < length_bytes; ++i) header_length |= std::size_t(static_cast<unsigned char>(bytes[8 + i])) << (8 * i);
  const std::size_t start = 8 + length_bytes + header_length;
  if (start > bytes.size()) throw bad("truncated .npy header");
  const std::string header = bytes.substr(8 + length_bytes, header_length);
  const std::string descr = npy_field(header, "descr"), order = npy_field(header, "fortran_order");
  const std::string shape = npy_field(header, "shape");
  const std::string want = "(" + std::to_string(alpha_bins) + ", " + std::to_string(cells) + ")";
  if (order != "False") throw bad("the array must be in C order (fortran_order False)");
  if (shape != want) throw bad("the array's shape is " + printable(shape) + "; --alpha-bins and --grid need " + want);
  const std::size_t count = std::size_t(alpha_bins) * std::size_t(cells);
  const std::size_t size = descr == "'<f8'" || descr == "'<i8'" ? 8 : descr == "'<f4'" || descr == "'<i4'" ? 4 : 0;
  if (size == 0) throw bad("dtype " + printable(descr) + " is not little-endian float64, float32, int64 or int32");
  if (bytes.size() - start != count * size) throw bad("the data are not " + std::to_string(count) + " values");
  std::vector<double> counts(count);
  const char* data = bytes.data() + start;
  if (descr == "'<f8'") widen<double>(data, count, counts);
  else if (descr == "'<f4'") widen<float>(data, count, counts);
  else if (descr == "'<i8'") widen<std::int64_t>(data, count, counts);
  else widen<std::int32_t>(data, count, counts);
  for (std::size_t i = 0; i < count; ++i)
    if (!(std::isfinite(counts[i]) && counts[i] >= 0))
      throw bad("negative or non-finite count at alpha bin " + std::to_string(i / std::size_t(cells)) + ", cell " +
                std::to_string(i % std::size_t(cells)));
  check_total(counts, path);
  return counts;
}

namespace {

// The fields of one line, split at runs of commas and white space (the first four kept in
// `field`); a `#` ends the line. Returns how many there are.
int split_fields(std::string_view line, std::string_view* field) {
  if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
  constexpr std::string_view kSeparators = ", \t\r";
  int n = 0;
  for (std::size_t at = line.find_first_not_of(kSeparators); at != std::string_view::npos; ++n) {
    const std::size_t end = std::min(line.find_first_of(kSeparators, at), line.size());
    if (n < 4) field[n] = line.substr(at, end - at);
    at = line.find_first_not_of(kSeparators, end);
  }
  return n;
}

// Text from a file for a message: bytes outside printable ASCII as \xNN (a NUL would end the
// line early), at most 80 characters.
std::string printable(std::string_view text) {
  std::string out;
  for (char c : text.substr(0, 80)) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u < 0x7f) {
      out += c;
    } else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02x", u);
      out += hex;
    }
  }
  return text.size() > 80 ? out + "..." : out;
}

// The counts' total must be finite and, for whole-number counts, exact in float64: a table
// whose weights sum to infinity, or whose count is not the sum of its cells, is no table.
void check_total(const std::vector<double>& counts, const std::string& path) {
  double total = 0;
  bool whole = true;
  for (double c : counts) {
    total += c;
    whole = whole && c == std::floor(c);
  }
  // A whole count at or past 2^53 may already be another number than the file's (2^53 + 1 reads
  // as 2^53): refused with the total that would be.
  if (!std::isfinite(total) || total > kMaxTotalWeight)
    throw std::runtime_error(path + ": the counts sum to " + std::to_string(total) + ", more than a table holds (2^62)");
  if (whole && total >= 0x1p53)
    throw std::runtime_error(path + ": the counts reach 2^53, where float64 no longer counts whole numbers exactly");
}

template <typename T>
bool parse(std::string_view text, T& value) {
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  return error == std::errc() && end == text.data() + text.size();
}

// The (alpha bin, cell) index of one row, or a reason it has none.
struct RowReader {
  const Table& layout;
  const DirectionGrid& grid;
  int fields;  // 3 or 4, from the first row

  std::string index_of(const std::string_view* f, std::size_t& index) const {
    if (fields == 3) {
      std::int64_t bin, cell;
      if (!parse(f[0], bin) || !parse(f[1], cell)) return "alpha_bin and cell must be whole numbers";
      if (bin < 0 || bin >= layout.alpha_bins) return "alpha_bin " + printable(f[0]) + " is not in 0.." + std::to_string(layout.alpha_bins - 1);
      if (cell < 0 || cell >= layout.cells) return "cell " + printable(f[1]) + " is not in 0.." + std::to_string(layout.cells - 1);
      index = std::size_t(bin) * std::size_t(layout.cells) + std::size_t(cell);
      return "";
    }
    double alpha, theta, phi;
    if (!parse(f[0], alpha) || !parse(f[1], theta) || !parse(f[2], phi)) return "alpha, theta and phi must be numbers";
    if (!(alpha >= 0 && alpha <= kPi)) return "alpha " + printable(f[0]) + " is not in [0, pi]";
    if (!(theta >= 0 && theta <= kPi)) return "theta " + printable(f[1]) + " is not in [0, pi]";
    if (!std::isfinite(phi)) return "phi must be finite";
    const auto& e = layout.alpha_edges;
    const std::size_t bin = std::min<std::size_t>(std::size_t(std::upper_bound(e.begin(), e.end(), alpha) - e.begin()) - 1,
                                                  std::size_t(layout.alpha_bins) - 1);
    const double s = std::sin(theta);
    index = bin * std::size_t(layout.cells) + std::size_t(grid.cell({s * std::cos(phi), s * std::sin(phi), std::cos(theta)}));
    return "";
  }
};

}  // namespace

std::vector<double> read_text_counts(const std::string& path, const Table& layout, const DirectionGrid& grid) {
  const std::string text = whole_file(path);
  if (text.find('\r') != std::string::npos && text.find('\n') == std::string::npos)
    throw std::runtime_error(path + ": its lines end in a carriage return alone; give them line feeds (\\n)");
  std::vector<double> counts(std::size_t(layout.alpha_bins) * std::size_t(layout.cells), 0.0);
  RowReader reader{layout, grid, 0};
  std::string_view f[4];
  std::size_t line_number = 0;
  for (std::size_t at = 0; at < text.size();) {
    const std::size_t end = std::min(text.find('\n', at), text.size());
    const std::string_view line(text.data() + at, end - at);
    at = end + 1;
    ++line_number;
    const int n = split_fields(line, f);
    if (n == 0) continue;
    auto bad = [&](const std::string& why) {
      return std::runtime_error(path + " line " + std::to_string(line_number) + ": " + why);
    };
    if (reader.fields == 0 && (n == 3 || n == 4)) reader.fields = n;
    if (n != reader.fields)
      throw bad(reader.fields == 0 ? "a row is 'alpha_bin cell count' or 'alpha theta phi count', got " + std::to_string(n) + " fields"
                                   : "expected " + std::to_string(reader.fields) + " fields as in the first row, got " + std::to_string(n));
    std::size_t index = 0;
    if (std::string why = reader.index_of(f, index); !why.empty()) throw bad(why);
    double count;
    if (!parse(f[n - 1], count) || !std::isfinite(count) || count < 0) throw bad("count '" + printable(f[n - 1]) + "' is not a finite number >= 0");
    counts[index] += count;
    if (!std::isfinite(counts[index])) throw bad("the counts of this row's cell sum beyond the largest number");
  }
  if (reader.fields == 0) throw std::runtime_error(path + ": no rows");
  check_total(counts, path);
  return counts;
}

}  // namespace stf
