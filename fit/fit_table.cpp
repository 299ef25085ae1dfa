#include "fit_table.h"

#include <Eigen/Dense>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <thread>

#include "alpha_marginal.h"
#include "expected_singular.h"
#include "fit_stages.h"
#include "alpha_tilt.h"
#include "cell_probability.h"
#include "grid.h"
#include "mirror.h"
#include "parallel.h"
#include "sh_fit.h"
#include "stf/once_scattered.h"
#include "stf/sh.h"
#include "vmf_fit.h"

namespace stf::fit {

FitSettings parse_model_spec(const std::string& spec) {
  const std::string allowed =
      "--model must be auto, vmf:K or hvmf:K (1..16), vmf:auto, hvmf:auto, sh:L (0..32) or sh:auto, got '" + spec + "'";
  if (spec == "auto") {
    FitSettings s;
    s.automatic = s.any_family = true;
    return s;
  }
  auto colon = spec.find(':');
  if (colon == std::string::npos) throw std::invalid_argument(allowed);
  std::string kind = spec.substr(0, colon), size = spec.substr(colon + 1);
  FitSettings s;
  s.hemispherical = kind == "hvmf";
  if (kind == "vmf" || kind == "hvmf") s.kind = ModelKind::kVmf;
  else if (kind == "sh") s.kind = ModelKind::kSh;
  else throw std::invalid_argument(allowed);
  if (size == "auto") {
    s.automatic = true;
    return s;
  }
  if (size.empty() || size.find_first_not_of("0123456789") != std::string::npos || size.size() > 3)
    throw std::invalid_argument(allowed);
  s.size = std::stoi(size);
  if ((s.kind == ModelKind::kVmf && (s.size < 1 || s.size > 16)) || (s.kind == ModelKind::kSh && s.size > 32))
    throw std::invalid_argument(allowed);
  return s;
}

std::vector<int> auto_candidates(ModelKind kind) {
  return kind == ModelKind::kVmf ? std::vector<int>{1, 2, 3, 4, 6, 8, 12, 14} : std::vector<int>{2, 4, 6, 8, 12, 16};
}

using namespace stages;


std::vector<double> smooth_headings(std::vector<double> headings, const std::vector<double>& escapes,
                                    std::vector<double>* slopes) {
  std::vector<double>& h = headings;
  // Each against the last bin with escapes: an empty bin's heading (atan2(0, 0) = 0) is none.
  for (std::size_t b = 0, last = 0, seen = 0; b < h.size(); ++b) {
    if (seen) h[b] -= 2 * kPi * std::round((h[b] - h[last]) / (2 * kPi));
    if (escapes[b] > 0) last = b, seen = 1;
  }
  const int bins = int(h.size());
  std::vector<double> smooth = h;
  if (slopes) slopes->assign(h.size(), 0.0);
  for (int b = 0; b < bins; ++b) {
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d right = Eigen::Vector3d::Zero();
    for (int j = std::max(0, b - kHeadingWindow); j <= std::min(bins - 1, b + kHeadingWindow); ++j) {
      const double d = j - b, w = escapes[std::size_t(j)] * (1 - std::abs(d) / (kHeadingWindow + 1));
      const Eigen::Vector3d x(1, d, d * d);
      normal += w * x * x.transpose(), right += w * x * h[std::size_t(j)];
    }
    const Eigen::FullPivLU<Eigen::Matrix3d> lu(normal);
    if (lu.rank() < 3) continue;
    const Eigen::Vector3d fit = lu.solve(right);
    smooth[std::size_t(b)] = fit(0);
    if (slopes) (*slopes)[std::size_t(b)] = fit(1);
  }
  return smooth;
}

std::vector<double> alpha_turns(const std::vector<double>& headings, const std::vector<double>& escapes,
                                const std::vector<double>& alpha_edges) {
  std::vector<double> slopes;
  smooth_headings(headings, escapes, &slopes);
  std::vector<double> turn(headings.size());
  for (std::size_t b = 0; b < turn.size(); ++b)
    turn[b] = std::clamp(slopes[b] / (alpha_edges[b + 1] - alpha_edges[b]), -kMaxFittedTurn, kMaxFittedTurn);
  return turn;
}


void compress_across_alpha(StfModel& m, const std::vector<double>& escapes) {
  const int bins = m.bins(), count = sh_count(m.band_limit), n = m.alpha_degree + 1;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(bins, n), Y = Eigen::MatrixXd::Zero(bins, count);
  for (int b = 0; b < bins; ++b) {
    double x = std::cos(0.5 * (m.alpha_edges[b] + m.alpha_edges[b + 1]));
    double w = m.status[b] == BinStatus::kFitted ? std::sqrt(escapes[b]) : 0.0;
    for (int j = 0; j < n; ++j) A(b, j) = w * std::cos(j * std::acos(x));  // T_j(x)
    for (int i = 0; i < count; ++i) Y(b, i) = w * m.sh[std::size_t(b) * count + i];
  }
  Eigen::MatrixXd C = A.colPivHouseholderQr().solve(Y);  // [n, count]
  m.sh_chebyshev.clear();
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < count; ++i) m.sh_chebyshev.push_back(C(j, i));
  for (int b = 0; b < bins; ++b) {
    double x = std::cos(0.5 * (m.alpha_edges[b] + m.alpha_edges[b + 1]));
    for (int i = 0; i < count; ++i) {
      double v = 0;
      for (int j = 0; j < n; ++j) v += C(j, i) * std::cos(j * std::acos(x));
      m.sh[std::size_t(b) * count + i] = v;
    }
  }
  m.rebuild_sh_tables();
}

namespace {

// --model auto: hemispherical lobes (hvmf) and SH at their held-out sizes, scored on the same
// held-out half; the one with the lower held-out negative log-likelihood is kept (with its
// report).
StfModel fit_any_family(const Table& t, const FitSettings& s, FitReport& r) {
  FitSettings one = s;
  one.any_family = false;
  FitReport reports[2];
  StfModel models[2];
  double nll[2];
  for (int i = 0; i < 2; ++i) {
    one.kind = i == 0 ? ModelKind::kVmf : ModelKind::kSh;
    one.hemispherical = i == 0;  // the lobes in the form that respects the outward hemisphere
    models[i] = fit_table(t, one, &reports[i]);
    if (cancelled(s)) return {};
    const FitReport& ri = reports[i];
    auto chosen = std::find(ri.candidates.begin(), ri.candidates.end(), ri.chosen_size) - ri.candidates.begin();
    nll[i] = ri.heldout_nll[std::size_t(chosen)];
  }
  const int best = nll[1] < nll[0] ? 1 : 0;
  r = reports[best];
  r.fit_time_s = reports[0].fit_time_s + reports[1].fit_time_s;
  r.family_heldout_nll = {nll[0], nll[1]};
  return models[best];
}

}  // namespace

StfModel fit_table(const Table& t, const FitSettings& s, FitReport* report) {
  if (std::string why = settings_error(t, s); !why.empty()) throw std::invalid_argument(why);
  if (wants_expected_singular_parts(t)) return fit_table(with_expected_singular_parts(t), s, report);
  if (s.any_family) {
    FitReport local;
    return fit_any_family(t, s, report ? *report : local);
  }
  auto start = std::chrono::steady_clock::now();
  std::unique_ptr<DirectionGrid> grid = make_grid(t.grid);
  // Everything is fitted and chosen on the escapes folded over the mirror symmetry (not where
  // the uncollided escapes are unknown: they would be folded off the pole); the diagnostics
  // are against the table as it is.
  Escapes seen{t, s.fold_mirror && t.uncollided_half[0] >= 0 ? mirror_cells(*grid) : std::vector<std::int64_t>{}};
  // The exit points inside each bin (the alpha marginal and tilts) and, for vMF lobes, how each
  // bin's density turns with them: the final fit sees a bin's counts as its density averaged over
  // its exit points, turned as the sampler turns it.
  const AlphaMarginal marginal = s.smooth_alpha ? smooth_alpha_marginal(t) : AlphaMarginal{};
  const std::vector<double> tilts =
      marginal.sub_escapes.empty() ? fit_alpha_tilts(t) : tilts_from_sub_counts(t, marginal.sub_escapes);
  if (s.kind == ModelKind::kVmf && s.turn && t.alpha_bins > 1) seen.set_turns(tilts);
  FitReport local;
  FitReport& r = report ? *report : local;
  r = FitReport{};
  QuadratureLevels levels(*grid);

  // Model size: given, or the candidate with the lowest held-out NLL, an unbiased estimate of
  // the model's cross-entropy with the truth. (A rule that prefers smaller models within noise
  // would err twice toward too few parameters: the candidates are fitted to half the escapes
  // the final model is.) Candidates go up in size until two in a row fail to lower the lowest
  // held-out NLL so far: the NLL of neighbouring sizes can sit on a plateau within a nat while
  // larger sizes gain tens (tau 1 g 0.9 at 1e5 paths, seed 7: 6 and 8 lobes within a nat, 14 lobes
  // 45 below), and the search must not end there.
  int size = s.size;
  ShSmoothing smoothing;
  BinFits chosen_fits;  // on half 0: where the final fit's lobes start
  std::vector<int> blend_widths;  // per bin; empty: none
  Pooling pool;  // how far each bin reaches for its neighbours' escapes (fit_bins)
  // SH chooses its smoothing on the held-out half; evenly split weights have none, and keep the
  // plain projection.
  if (s.automatic || (s.kind == ModelKind::kSh && t.halves != Halves::kEven)) {
    std::vector<int> sizes = s.automatic ? auto_candidates(s.kind) : std::vector<int>{s.size};
    std::vector<HeldOut> scores;
    std::vector<ShSmoothing> ts;
    std::vector<BinFits> half_fits;
    double lowest = std::numeric_limits<double>::infinity();
    int misses = 0;
    for (int candidate : sizes) {
      ShSmoothing best_t;
      BinFits fitted;
      scores.push_back(heldout_for_size(seen, s, candidate, *grid, levels, best_t, fitted,
                                        half_fits.empty() ? nullptr : &half_fits.back()));
      half_fits.push_back(std::move(fitted));
      ts.push_back(best_t);
      if (cancelled(s)) return {};
      if (scores.back().nll < lowest) lowest = scores.back().nll, misses = 0;
      else if (++misses == 2) break;
    }
    sizes.resize(scores.size());
    std::size_t best = 0;
    for (std::size_t i = 1; i < scores.size(); ++i)
      if (scores[i].nll < scores[best].nll) best = i;
    for (std::size_t i = 0; i < scores.size(); ++i) {
      r.candidates.push_back(sizes[i]);
      r.heldout_nll.push_back(scores[i].nll);
      r.heldout_nll_error.push_back(difference_error(seen, 1, scores[i], scores[best]));
    }
    size = sizes[best];
    smoothing = ts[best];
    chosen_fits = half_fits[best];
    HeldOut chosen_score = std::move(scores[best]);
    if (s.automatic && s.kind == ModelKind::kVmf && s.pool_neighbours && t.alpha_bins > 1) {
      pool.bin = choose_pooling(seen, s, *grid, levels, sizes, half_fits, best, size, chosen_fits, chosen_score, r);
      if (cancelled(s)) return {};
      // Bin by bin for hemispherical lobes only: with plain lobes the choice came out worse on
      // one medium of the study (tau 4.5 g -0.5 at 1e5 paths: 0.061 against 0.053) and fits
      // took up to 12 s (docs/studies/2026-12-fit-measurements.md, "Pools chosen bin by bin").
      if (s.hemispherical) wide_pooling(seen, s, *grid, levels, size, pool.bin, chosen_fits, chosen_score);
      if (cancelled(s)) return {};
    }
    if (s.automatic && t.alpha_bins > 1) {
      // A turning model's sampler turns each blended neighbour's density with the exit point: the
      // held-out half scores the blend so.
      TurnedNeighbours turned;
      if (!seen.turns.empty() && s.max_blend > 0) turned = turned_neighbours(chosen_fits, seen.turns, levels, s.max_blend, s);
      if (cancelled(s)) return {};
      BlendChoice c = choose_blend(seen, chosen_score, s.max_blend, turned);
      r.blend_heldout_nll = c.nll;
      r.blend_heldout_nll_error = c.error;
      r.blend_width = c.width;
      r.blend_by_bin_gain = c.by_bin_gain;
      r.blend_by_bin_error = c.by_bin_error;
      blend_widths = c.widths;
    }
  }

  std::unique_ptr<ShProjector> projector;
  if (s.kind == ModelKind::kSh) projector = std::make_unique<ShProjector>(*grid, size);
  BinFits fits = fit_bins(seen, -1, s.kind, size, levels, projector.get(), s,
                          chosen_fits.status.empty() ? nullptr : &chosen_fits, &pool);
  if (cancelled(s)) return {};

  StfModel m;
  m.kind = s.kind;
  m.sigma_s = t.medium.sigma_s, m.sigma_a = t.medium.sigma_a, m.g = t.medium.g;
  m.radius = t.medium.radius, m.tau = t.medium.tau(), m.albedo = t.medium.albedo();
  double paths = double(t.paths);
  const SingularParts exact = singular_parts(t);
  const RestProbabilities rest = rest_probabilities(t, exact);
  m.absorbed_fraction = rest.absorbed;
  m.truncated_fraction = rest.truncated;
  m.alpha_edges = t.alpha_edges;
  m.status = fits.status;
  // The rest (all but the once-scattered part) per alpha bin, in paths: the fitted escapes and,
  // in bin 0, the uncollided delta.
  std::vector<double> escapes = marginal.bin_escapes.empty() ? seen.total : marginal.bin_escapes;
  for (double& e : escapes) e *= rest.fitted_scale;
  escapes[0] += exact.uncollided * paths;
  double escaped = sum(escapes);
  m.escape_probability = std::min(1.0, escaped / paths + exact.once);
  m.once_fraction = m.escape_probability > 0 ? exact.once / m.escape_probability : 0;
  m.uncollided_fraction = escaped > 0 ? exact.uncollided * paths / escaped : 0;
  m.alpha_probability = escaped > 0 ? escapes : uniform_alpha(t.alpha_edges);
  for (double& p : m.alpha_probability) p /= escaped > 0 ? escaped : 1;
  m.alpha_tilt = tilts;
  if (!blend_widths.empty()) {
    m.alpha_blend = *std::max_element(blend_widths.begin(), blend_widths.end());
    if (std::any_of(blend_widths.begin(), blend_widths.end(), [&](int h) { return h != m.alpha_blend; }))
      m.alpha_blend_width = blend_widths;
  }
  for (const BinTurn& turn : seen.turns) m.alpha_turn.push_back(turn.rate);
  if (s.kind == ModelKind::kVmf) {
    m.lobes = size;
    for (const auto& lobes : fits.lobes) m.vmf.insert(m.vmf.end(), lobes.begin(), lobes.end());
    m.hemispherical = s.hemispherical;
    m.rebuild_lobe_norms();
  } else {
    m.band_limit = size;
    m.sh_nz = std::max(32, 4 * size);
    for (int b = 0; b < t.alpha_bins; ++b) {
      std::vector<double> c = fits.sh[b];
      if (m.status[b] != BinStatus::kEmpty) smooth_sh(c, size, smoothing);
      m.sh.insert(m.sh.end(), c.begin(), c.end());
    }
    m.rebuild_sh_tables();
    if (s.alpha_degree >= 0 && escaped > 0) {
      m.alpha_degree = std::min(s.alpha_degree, t.alpha_bins - 1);
      compress_across_alpha(m, escapes);
    }
  }

  // Diagnostics against the full table, with the model as a sampler will use it.
  r.bins.resize(t.alpha_bins);
  const int params_per_bin = s.kind == ModelKind::kVmf ? 5 * size - 1 : sh_count(size) - 1;
  for_each_bin(t.alpha_bins, s, [&](int b) {
    std::vector<double> counts = bin_counts(t, -1, b);
    BinDiagnostics& d = r.bins[b];
    d.escapes = sum(counts);
    d.components = size;
    if (s.kind == ModelKind::kVmf) {
      d.components = 0;
      for (int k = 0; k < size; ++k) d.components += m.vmf[std::size_t(b) * size + k].weight > 0;
    }
    if (d.escapes <= 0 || m.status[b] != BinStatus::kFitted) return;
    std::vector<double> p = s.kind == ModelKind::kVmf
                                ? bin_probabilities(fits, b, s.kind, size, {}, levels, {})
                                : density_cell_probabilities([&](const Vec3& w) { return m.direction_pdf(b, w); },
                                                             levels.at(2));
    d.deviance = poisson_deviance(counts, p);
    double chi2 = 0;
    int used = 0;
    for (std::int64_t c = 0; c < t.cells; ++c) {
      double mu = d.escapes * p[c];
      if (mu <= 0) continue;
      chi2 += (counts[c] - mu) * (counts[c] - mu) / mu;
      ++used;
    }
    d.chi2_dof = chi2 / std::max(1, used - params_per_bin);
  });
  r.chosen_size = size;
  r.singular_parts = singular_parts_source(t);
  r.heldout_halves = t.halves == Halves::kTallied ? "tallied" : t.halves == Halves::kThinned ? "thinned" : "none";
  r.pools = pool.bin;
  r.smoothing = smoothing.t;
  r.alpha_penalty = marginal.bin_escapes.empty() ? -1 : marginal.penalty;
  r.lanczos_window = smoothing.lanczos;
  r.fit_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return m;
}

}  // namespace stf::fit
