// The model of the final fits, and its diagnostics (fit_stages.h).
#include "fit_stages.h"

namespace stf::fit::stages {

namespace {

// The medium, the exact parts and the rest's probabilities, and the alpha marginal of all but
// the once-scattered part: the fitted escapes and, in bin 0, the uncollided delta. Returns the
// escapes per bin (in paths) the marginal was made of.
std::vector<double> add_outcomes(StfModel& m, const Escapes& e, const AlphaShape& alpha) {
  const Table& t = e.table;
  m.sigma_s = t.medium.sigma_s, m.sigma_a = t.medium.sigma_a, m.g = t.medium.g;
  m.radius = t.medium.radius, m.tau = t.medium.tau(), m.albedo = t.medium.albedo();
  const double paths = double(t.paths);
  const SingularParts exact = singular_parts(t);
  const RestProbabilities rest = rest_probabilities(t, exact);
  // Probabilities, whatever rounding did to a medium at the edge of its range (tau ~ 1e-300).
  m.absorbed_fraction = std::clamp(rest.absorbed, 0.0, 1.0);
  m.truncated_fraction = std::clamp(rest.truncated, 0.0, 1.0);
  m.alpha_edges = t.alpha_edges;
  std::vector<double> escapes = alpha.marginal.bin_escapes.empty() ? e.total : alpha.marginal.bin_escapes;
  for (double& x : escapes) x *= rest.fitted_scale;
  escapes[0] += exact.uncollided * paths;
  const double escaped = sum(escapes);
  m.escape_probability = std::min(1.0, escaped / paths + exact.once);
  m.once_fraction = m.escape_probability > 0 ? exact.once / m.escape_probability : 0;
  m.uncollided_fraction = escaped > 0 ? exact.uncollided * paths / escaped : 0;
  m.alpha_probability = escaped > 0 ? escapes : uniform_alpha(t.alpha_edges);
  for (double& p : m.alpha_probability) p /= escaped > 0 ? escaped : 1;
  m.alpha_tilt = alpha.tilts;
  return escapes;
}

// Each bin's lobes, or its SH coefficients smoothed as chosen (and compressed across alpha).
void add_directions(StfModel& m, const FitSettings& s, const SizeChoice& c, const BinFits& fits,
                    const std::vector<double>& escapes) {
  const int size = c.size;
  if (s.kind == ModelKind::kVmf) {
    m.lobes = size;
    for (const auto& lobes : fits.lobes) m.vmf.insert(m.vmf.end(), lobes.begin(), lobes.end());
    m.hemispherical = s.hemispherical;
    m.lifted = s.lifted;
    m.rebuild_lobe_norms();
    return;
  }
  m.band_limit = size;
  m.sh_nz = sh_table_rows(size);
  for (int b = 0; b < m.bins(); ++b) {
    std::vector<double> coefficients = fits.sh[std::size_t(b)];
    if (m.status[std::size_t(b)] != BinStatus::kEmpty) smooth_sh(coefficients, size, c.smoothing);
    m.sh.insert(m.sh.end(), coefficients.begin(), coefficients.end());
  }
  m.rebuild_sh_tables();
  if (s.alpha_degree >= 0 && sum(escapes) > 0) {
    m.alpha_degree = std::min(s.alpha_degree, m.bins() - 1);
    compress_across_alpha(m, escapes);
  }
}

}  // namespace

StfModel assemble_model(const Escapes& e, const FitSettings& s, const AlphaShape& alpha, const SizeChoice& choice,
                        const Neighbours& near, const BinFits& fits) {
  StfModel m;
  m.kind = s.kind;
  const std::vector<double> escapes = add_outcomes(m, e, alpha);
  m.status = fits.status;
  const std::vector<int>& widths = near.blend_widths;
  if (!widths.empty()) {
    m.alpha_blend = *std::max_element(widths.begin(), widths.end());
    if (std::any_of(widths.begin(), widths.end(), [&](int h) { return h != m.alpha_blend; }))
      m.alpha_blend_width = widths;
  }
  for (const BinTurn& turn : e.turns) m.alpha_turn.push_back(turn.rate);
  add_directions(m, s, choice, fits, escapes);
  return m;
}

void diagnose(const BinFits& fits, const FitSettings& s, const StfModel& m, const QuadratureLevels& levels, int size,
              FitReport& r) {
  const Table& t = *fits.table;
  r.bins.resize(std::size_t(t.alpha_bins));
  const int params_per_bin = s.kind == ModelKind::kVmf ? 5 * size - 1 : sh_count(size) - 1;
  for_each_bin(t.alpha_bins, s, "diagnostics", [&](int b) {
    std::vector<double> counts = bin_counts(t, -1, b);
    BinDiagnostics& d = r.bins[std::size_t(b)];
    d.escapes = sum(counts);
    d.components = size;
    if (s.kind == ModelKind::kVmf) {
      d.components = 0;
      for (int k = 0; k < size; ++k) d.components += m.vmf[std::size_t(b) * size + k].weight > 0;
    }
    if (d.escapes <= 0 || m.status[std::size_t(b)] != BinStatus::kFitted) return;
    std::vector<double> p = s.kind == ModelKind::kVmf
                                ? bin_probabilities(fits, b, {}, levels, {}, Tails::kKeep)
                                : density_cell_probabilities([&](const Vec3& w) { return m.direction_pdf(b, w); },
                                                             levels.at(kShMeasureLevel));
    d.deviance = poisson_deviance(counts, p);
    double chi2 = 0;
    int used = 0;
    for (std::int64_t c = 0; c < t.cells; ++c) {
      double mu = d.escapes * p[std::size_t(c)];
      if (mu <= 0) continue;
      chi2 += (counts[std::size_t(c)] - mu) * (counts[std::size_t(c)] - mu) / mu;
      ++used;
    }
    d.chi2_dof = chi2 / std::max(1, used - params_per_bin);
  });
}

}  // namespace stf::fit::stages
