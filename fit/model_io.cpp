#include "stf/fit/model_io.h"

#include <H5Cpp.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "stf/core/files.h"
#include "stf/core/h5io.h"
#include "stf/pack.h"
#include "stf/sh.h"

namespace stf::fit {

using namespace h5;

namespace {

// The one layout stf reads; files of other versions are refused in one line naming theirs and
// the fix (fit the table again).
constexpr int kFormatVersion = 6;

// The root's double attributes, in the order they are written: the medium's (none when the
// table named no medium) and the fractions.
using Field = std::pair<const char*, double StfModel::*>;
constexpr Field kMedium[] = {{"sigma_s", &StfModel::sigma_s}, {"sigma_a", &StfModel::sigma_a},
                             {"g", &StfModel::g},             {"radius", &StfModel::radius},
                             {"tau", &StfModel::tau},         {"albedo", &StfModel::albedo}};
constexpr Field kFractions[] = {{"escape_probability", &StfModel::escape_probability},
                                {"absorbed_fraction", &StfModel::absorbed_fraction},
                                {"truncated_fraction", &StfModel::truncated_fraction},
                                {"uncollided_fraction", &StfModel::uncollided_fraction},
                                {"once_fraction", &StfModel::once_fraction}};

// The root attributes: the medium, the fractions and where the model came from.
void put_header(H5::H5File& file, const StfModel& m, const FitReport& r, const Provenance& p) {
  put_attr(file, "format", std::string("stf-model"));
  put_attr(file, "format_version", kFormatVersion);
  put_attr(file, "model", std::string(m.kind == ModelKind::kVmf ? "vmf" : "sh"));
  put_attr(file, "model_spec", p.model_spec);
  if (m.has_medium())  // a model of a table that named no medium carries none
    for (const auto& [name, field] : kMedium) put_attr(file, name, m.*field);
  for (const auto& [name, field] : kFractions) put_attr(file, name, m.*field);
  put_attr(file, "hemispherical", int(m.hemispherical));
  if (m.lifted) put_attr(file, "lifted", 1);  // absent: 0, so that other models' files stay as they were
  put_attr(file, "alpha_blend", m.alpha_blend);
  put_attr(file, "fit_time_s", r.fit_time_s);
  put_attr(file, "model_bytes", m.packed_bytes());
  put_attr(file, "generator", std::string("stf " STF_VERSION));
  put_attr(file, "source_table", p.source_table);
  if (p.table) {
    put_attr(file, "source_paths", p.table->paths);
    put_attr(file, "source_seed", p.table->seed);
    put_attr(file, "source_grid", p.table->grid);
    put_attr(file, "source_generator", p.table->generator);
    put_attr(file, "source_table_bytes", std::int64_t(p.table->alpha_bins) * p.table->cells * 4);
  }
  if (p.tolerance > 0) {
    put_attr(file, "tolerance", p.tolerance);
    put_attr(file, "tv_bound", p.tv_bound);
    put_attr(file, "tolerance_met", int(p.tolerance_met));
    put_attr(file, "fit_grid", p.fit_grid);
    put_attr(file, "heldout_table", p.heldout_table);
    put_attr(file, "heldout_paths", p.heldout_paths);
  }
}

void put_alpha(H5::H5File& file, const StfModel& m) {
  const hsize_t bins = hsize_t(m.bins());
  H5::Group alpha = file.createGroup("/alpha");
  put_dataset(alpha, "edges", {bins + 1}, m.alpha_edges.data());
  put_dataset(alpha, "probability", {bins}, m.alpha_probability.data());
  std::vector<std::int32_t> status(bins);
  for (std::size_t b = 0; b < bins; ++b) status[b] = std::int32_t(m.status[b]);
  put_dataset(alpha, "status", {bins}, status.data());
  if (!m.alpha_tilt.empty()) put_dataset(alpha, "tilt", {bins}, m.alpha_tilt.data());
  if (!m.alpha_turn.empty()) put_dataset(alpha, "turn", {bins}, m.alpha_turn.data());
  if (!m.alpha_blend_width.empty()) {
    const std::vector<std::int32_t> width(m.alpha_blend_width.begin(), m.alpha_blend_width.end());
    put_dataset(alpha, "blend", {bins}, width.data());
  }
}

void put_directions(H5::H5File& file, const StfModel& m, const FitReport& r) {
  const hsize_t bins = hsize_t(m.bins());
  if (m.kind == ModelKind::kVmf) {
    H5::Group g = file.createGroup("/vmf");
    put_attr(g, "lobes", m.lobes);
    const hsize_t k = hsize_t(m.lobes);
    std::vector<double> weight, kappa, mean;
    for (const VmfLobe& l : m.vmf) {
      weight.push_back(l.weight);
      kappa.push_back(l.kappa);
      mean.insert(mean.end(), {l.mean.x, l.mean.y, l.mean.z});
    }
    put_dataset(g, "weight", {bins, k}, weight.data());
    put_dataset(g, "kappa", {bins, k}, kappa.data());
    put_dataset(g, "mean", {bins, k, 3}, mean.data());
  } else {
    H5::Group g = file.createGroup("/sh");
    put_attr(g, "band_limit", m.band_limit);
    put_attr(g, "table_nz", m.sh_nz);
    put_attr(g, "smoothing", r.smoothing);
    put_attr(g, "window", std::string(r.lanczos_window ? "lanczos" : "none"));
    put_dataset(g, "coefficients", {bins, hsize_t(sh_count(m.band_limit))}, m.sh.data());
    put_attr(g, "alpha_degree", m.alpha_degree);
    if (m.alpha_degree >= 0)
      put_dataset(g, "chebyshev", {hsize_t(m.alpha_degree + 1), hsize_t(sh_count(m.band_limit))},
                  m.sh_chebyshev.data());
  }
}

void put_diagnostics(H5::H5File& file, const StfModel& m, const FitReport& r) {
  const hsize_t bins = hsize_t(m.bins());
  H5::Group d = file.createGroup("/diagnostics");
  std::vector<double> escapes, deviance, chi2;
  std::vector<std::int32_t> components;
  for (const BinDiagnostics& b : r.bins) {
    escapes.push_back(b.escapes);
    deviance.push_back(b.deviance);
    chi2.push_back(b.chi2_dof);
    components.push_back(b.components);
  }
  put_dataset(d, "escapes", {bins}, escapes.data());
  put_dataset(d, "deviance", {bins}, deviance.data());
  put_dataset(d, "chi2_dof", {bins}, chi2.data());
  put_dataset(d, "components", {bins}, components.data());
  if (!r.candidates.empty()) {
    H5::Group sel = file.createGroup("/selection");
    put_attr(sel, "chosen", r.chosen_size);
    std::vector<std::int32_t> cand(r.candidates.begin(), r.candidates.end());
    const hsize_t n = cand.size();
    put_dataset(sel, "candidates", {n}, cand.data());
    put_dataset(sel, "heldout_nll", {n}, r.heldout_nll.data());
    put_dataset(sel, "heldout_nll_error", {n}, r.heldout_nll_error.data());
  }
}

}  // namespace

std::string model_file(const StfModel& m, const FitReport& r, const Provenance& p) {
  // What the reader would refuse is not written.
  if (std::string why = model_error(m); !why.empty()) throw std::runtime_error("the model is not valid: " + why);
  try {
    H5::Exception::dontPrint();
    MemoryFile memory;
    put_header(memory.file(), m, r, p);
    put_alpha(memory.file(), m);
    put_directions(memory.file(), m, r);
    put_diagnostics(memory.file(), m, r);
    return memory.bytes();
  } catch (const H5::Exception& e) {
    throw std::runtime_error("cannot write a model: " + e.getDetailMsg());
  }
}

void write_model(const StfModel& m, const FitReport& r, const Provenance& p,
                 const std::string& path) {
  replace_file(path, model_file(m, r, p));
}

namespace {

// The root attributes: format and version, kind, medium (absent: none named) and fractions.
StfModel get_header(H5::H5File& file) {
  if (get_string(file, "format") != "stf-model")
    throw std::runtime_error("not an stf model (format attribute is not 'stf-model')");
  if (const int version = get_int(file, "format_version"); version != kFormatVersion)
    throw std::runtime_error("model format_version " + std::to_string(version) +
                             (version < kFormatVersion ? " is older" : " is newer") + " than this stf reads (" +
                             std::to_string(kFormatVersion) + "): fit its table again with this stf (stf fit)");
  StfModel m;
  std::string kind = get_string(file, "model");
  if (kind != "vmf" && kind != "sh") throw std::runtime_error("unknown model kind '" + kind + "'");
  m.kind = kind == "vmf" ? ModelKind::kVmf : ModelKind::kSh;
  const bool medium = has_attr(file, "tau");
  for (const auto& [name, field] : kMedium) m.*field = medium ? get_double(file, name) : std::nan("");
  for (const auto& [name, field] : kFractions) m.*field = get_double(file, name, 0, 1);
  m.hemispherical = get_int(file, "hemispherical", 0, 1) != 0;
  m.lifted = has_attr(file, "lifted") && get_int(file, "lifted", 0, 1) != 0;
  m.alpha_blend = get_int(file, "alpha_blend", 0, StfModel::kMaxBlend);
  return m;
}

// /alpha: the marginal, edges and status, and the optional tilts, turns and blend widths.
void get_alpha(H5::H5File& file, StfModel& m) {
  const std::vector<hsize_t> shape = dataset_shape(file, "/alpha/probability");
  if (shape.size() != 1 || shape[0] < 1 || shape[0] > hsize_t(kMaxModelBins))
    throw std::runtime_error("/alpha/probability must hold 1.." + std::to_string(kMaxModelBins) + " alpha bins");
  m.alpha_probability = get_dataset(file, "/alpha/probability", shape);
  const hsize_t bins = m.alpha_probability.size();
  m.alpha_edges = get_dataset(file, "/alpha/edges", {bins + 1});
  for (std::int32_t s : get_int_dataset(file, "/alpha/status", {bins})) m.status.push_back(BinStatus(s));
  if (has_object(file, "/alpha/tilt")) m.alpha_tilt = get_dataset(file, "/alpha/tilt", {bins});
  if (has_object(file, "/alpha/turn")) m.alpha_turn = get_dataset(file, "/alpha/turn", {bins});
  if (has_object(file, "/alpha/blend"))
    for (std::int32_t h : get_int_dataset(file, "/alpha/blend", {bins})) m.alpha_blend_width.push_back(h);
}

// /vmf or /sh: the bins' direction densities.
void get_directions(H5::H5File& file, StfModel& m) {
  const hsize_t bins = m.alpha_probability.size();
  if (m.kind == ModelKind::kVmf) {
    m.lobes = get_int(open_group(file, "/vmf"), "lobes", 1, kMaxLobes);
    const hsize_t k = hsize_t(m.lobes);
    std::vector<double> w = get_dataset(file, "/vmf/weight", {bins, k});
    std::vector<double> kappa = get_dataset(file, "/vmf/kappa", {bins, k});
    std::vector<double> mean = get_dataset(file, "/vmf/mean", {bins, k, 3});
    for (std::size_t i = 0; i < w.size(); ++i) m.vmf.push_back({w[i], kappa[i], {mean[3 * i], mean[3 * i + 1], mean[3 * i + 2]}});
    return;
  }
  H5::Group g = open_group(file, "/sh");
  m.band_limit = get_int(g, "band_limit", 0, kMaxBandLimit);
  m.sh_nz = get_int(g, "table_nz", 1, kMaxShNz);
  m.alpha_degree = get_int(g, "alpha_degree", -1, kMaxAlphaDegree);
  // Before the tables are built: their size follows from these.
  if (std::string why = model_size_error(true, double(bins), m.band_limit, m.sh_nz, m.alpha_degree); !why.empty())
    throw std::runtime_error(why);
  m.sh = get_dataset(file, "/sh/coefficients", {bins, hsize_t(sh_count(m.band_limit))});
  if (m.alpha_degree >= 0)
    m.sh_chebyshev =
        get_dataset(file, "/sh/chebyshev", {hsize_t(m.alpha_degree + 1), hsize_t(sh_count(m.band_limit))});
  m.rebuild_sh_tables();
}

}  // namespace

StfModel read_model(const std::string& path) {
  return read_file(path, [](H5::H5File& file) {
    StfModel m = get_header(file);
    get_alpha(file, m);
    get_directions(file, m);
    if (std::string why = model_error(m); !why.empty()) throw std::runtime_error(why);
    m.rebuild_lobe_norms();
    return m;
  });
}

ModelSummary read_model_summary(const std::string& path) {
  StfModel m = read_model(path);
  ModelSummary s;
  s.kind = m.family();
  s.size = m.kind == ModelKind::kVmf ? m.lobes : m.band_limit;
  s.alpha_bins = m.bins();
  s.bytes = m.packed_bytes();
  return read_file(path, [&](H5::H5File& file) {
    if (has_attr(file, "source_grid")) s.grid = get_string(file, "source_grid");
    if (has_attr(file, "source_paths")) s.paths = get_int64(file, "source_paths");
    if (has_attr(file, "tolerance")) {
      s.tolerance = get_double(file, "tolerance");
      s.tv_bound = get_double(file, "tv_bound");
      s.tolerance_met = get_int(file, "tolerance_met") != 0;
      s.grid = get_string(file, "fit_grid");
    }
    return s;
  });
}

std::vector<double> read_chi2_dof(const std::string& path) {
  return read_file(path, [](H5::H5File& file) { return get_dataset(file, "/diagnostics/chi2_dof", {}); });
}

StfModel read_model_or_pack(const std::string& path) {
  ReadingInput reading;
  std::error_code code;
  if (std::filesystem::exists(path, code) && !std::filesystem::is_regular_file(path, code))
    throw std::runtime_error("'" + path + "' is not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("'" + path + "': " + std::strerror(errno));
  char magic[8] = {};
  in.read(magic, 8);
  if (std::string(magic, 8) == "STFPACK1") {
    std::vector<PackEntry> entries;
    std::string error;
    if (!read_pack_file(path, entries, error)) throw std::runtime_error(path + ": " + error);
    if (entries.empty()) throw std::runtime_error(path + ": the pack holds no model");
    return entries.front().model;
  }
  if (file_format(path) != "stf-model") throw std::runtime_error("'" + path + "' is neither an stf model nor an stf pack");
  return read_model(path);
}

std::string file_format(const std::string& path) {
  try {
    H5::Exception::dontPrint();
    ReadingInput reading;
    H5::H5File file = open_file(path);
    return has_attr(file, "format") ? get_string(file, "format") : "";
  } catch (const H5::Exception&) {
    return "";
  } catch (const std::runtime_error& e) {  // a checksum that does not match (named), a bad attribute
    const std::string what = e.what();
    throw std::runtime_error(what.rfind(path, 0) == 0 ? what : path + ": " + what);
  }
}

}  // namespace stf::fit
