#include "stf/measure/tolerance.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>

#include "stf/fit/alpha_tilt.h"
#include "stf/measure/evaluate.h"
#include "stf/core/grid.h"
#include "stf/fit/parallel.h"
#include "stf/fit/vmf_fit.h"

namespace stf::measure {

using namespace stf::fit;  // the fit this measures: its models, cell integrals and settings

namespace {

// Where each (alpha bin, cell) of a table goes when coarsened, and its share of that group:
// the bin's share of the group's area on the unit sphere times the cell's share of its
// parent's solid angle.
struct Coarsening {
  std::string grid;                  // the coarse grid
  std::int64_t cells = 0;            // its cell count
  std::vector<std::int64_t> parent;  // [cells] fine cell -> coarse cell
  std::vector<double> parent_solid_angle;
  std::vector<std::int64_t> group;  // [alpha_bins * cells] -> coarse (bin, cell)
  std::vector<double> share;        // [alpha_bins * cells]
};

Coarsening make_coarsening(const Table& t, int f, int levels) {
  if (f < 1 || t.alpha_bins % f != 0)
    throw std::invalid_argument("alpha factor " + std::to_string(f) + " does not divide " +
                                std::to_string(t.alpha_bins) + " bins");
  std::unique_ptr<DirectionGrid> grid = make_grid(t.grid);
  Coarsening k;
  k.grid = grid->coarser(levels);
  if (k.grid.empty())
    throw std::invalid_argument(t.grid + " cannot be halved " + std::to_string(levels) + " times");
  k.cells = t.cells >> (2 * levels);
  k.parent = grid->parents(levels);
  k.parent_solid_angle.assign(k.cells, 0.0);
  for (std::int64_t c = 0; c < t.cells; ++c) k.parent_solid_angle[k.parent[c]] += t.solid_angle[c];
  k.group.resize(std::size_t(t.alpha_bins) * t.cells);
  k.share.resize(k.group.size());
  for (int a = 0; a < t.alpha_bins; ++a) {
    const int j = a / f;
    const double alpha_share = area_share(t, a, f);
    for (std::int64_t c = 0; c < t.cells; ++c) {
      const std::size_t i = std::size_t(a) * t.cells + c;
      k.group[i] = std::int64_t(j) * k.cells + k.parent[c];
      k.share[i] = alpha_share * t.solid_angle[c] / k.parent_solid_angle[k.parent[c]];
    }
  }
  return k;
}

std::vector<double> normalised(std::vector<double> y) {
  double total = 0;
  for (double v : y) total += v;
  if (total > 0)
    for (double& v : y) v /= total;
  return y;
}

std::vector<double> group_sums(const std::vector<double>& y, const Coarsening& k,
                               std::size_t groups) {
  std::vector<double> g(groups, 0.0);
  for (std::size_t i = 0; i < y.size(); ++i) g[k.group[i]] += y[i];
  return g;
}

}  // namespace

Table coarsen_table(const Table& t, int f, int levels) {
  const Coarsening k = make_coarsening(t, f, levels);
  Table c = t;
  c.grid = k.grid;
  c.alpha_bins = t.alpha_bins / f;
  c.cells = k.cells;
  c.alpha_edges.clear();
  for (int j = 0; j <= c.alpha_bins; ++j)
    c.alpha_edges.push_back(t.alpha_edges[std::size_t(j) * f]);
  std::unique_ptr<DirectionGrid> grid = make_grid(k.grid);
  c.direction.resize(k.cells);
  for (std::int64_t i = 0; i < k.cells; ++i) {
    Vec3 d = grid->centre(i);
    c.direction[i] = {d.x, d.y, d.z};
  }
  c.solid_angle = k.parent_solid_angle;
  for (int h = 0; h < 2; ++h)
    c.weight_half[h] = group_sums(t.weight_half[h], k, std::size_t(c.alpha_bins) * k.cells);
  c.once.clear();
  for (const auto& [key, w] : t.once) c.once[2 * std::uint64_t(k.group[key >> 1]) + (key & 1)] += w;
  group_sub_bins(t, f, c);
  return c;
}

double coarsening_tv(const Table& t, const Table& other, int f, int levels) {
  const Coarsening k = make_coarsening(t, f, levels);
  const std::size_t groups = std::size_t(t.alpha_bins / f) * k.cells;
  const std::vector<double> ya = normalised(t.weight_half[0]), yb = normalised(t.weight_half[1]);
  const std::vector<double> yo = normalised(other.weight());  // the exit distribution
  auto empty = [](const std::vector<double>& y) {
    return std::all_of(y.begin(), y.end(), [](double v) { return v == 0; });
  };
  if (empty(ya) || empty(yb) || empty(yo))
    return std::numeric_limits<double>::infinity();  // cannot tell
  const std::vector<double> ga = group_sums(ya, k, groups), gb = group_sums(yb, k, groups),
                            go = group_sums(yo, k, groups);
  // E[(ya - M ya)(yb - M yb)] = (p - M p)^2 for the independent halves; the weights come from
  // the other table, independent of both, as in certify().
  double chi2 = 0, weight_sum = 0;
  for (std::size_t i = 0; i < ya.size(); ++i) {
    const double w = std::max(k.share[i] * go[k.group[i]], yo[i]);
    weight_sum += w;
    if (w > 0)
      chi2 += (ya[i] - k.share[i] * ga[k.group[i]]) * (yb[i] - k.share[i] * gb[k.group[i]]) / w;
  }
  return 0.5 * std::sqrt(std::max(0.0, chi2) * weight_sum);
}

namespace {

// BinnedModel::bin of every reference bin, the smooth cell probabilities computed on the fit's
// threads: once per model bin (a blended bin also draws on its neighbours'), or, where the
// model turns, per slice of exit angle, in each model bin's own cache. Empty when cancelled:
// the bins skipped then hold nothing.
std::vector<std::pair<double, std::vector<double>>> binned_in_parallel(const StfModel& model, const BinnedModel& binned,
                                                                     const QuadratureLevels& levels,
                                                                     const FitSettings& settings) {
  const int bins = model.bins(), f = binned.group();
  std::vector<std::pair<double, std::vector<double>>> out(std::size_t(bins) * f);
  if (!model.alpha_turn.empty() || model.lifted) {  // cells that change with the exit angle
    for_each_bin(bins, settings, "certificate", [&](int j) {
      SmoothCellCache cache(model, levels);
      for (int a = j * f; a < (j + 1) * f; ++a) out[std::size_t(a)] = binned.bin(a, std::ref(cache));
    });
    if (cancelled(settings)) out.clear();
    return out;
  }
  std::vector<std::vector<double>> cell_probability(bins);
  for_each_bin(bins, settings, "certificate", [&](int j) { cell_probability[j] = smooth_cell_probabilities(model, j, levels); });
  if (cancelled(settings)) return {};
  const auto cells_of = [&](int j, double, double, double) -> const std::vector<double>& {
    return cell_probability[std::size_t(j)];
  };
  for (std::size_t a = 0; a < out.size(); ++a) out[a] = binned.bin(int(a), cells_of);
  return out;
}

}  // namespace

std::string heldout_error(const Table& table, const Table& heldout) {
  if (heldout.alpha_bins != table.alpha_bins || heldout.grid != table.grid || heldout.seed == table.seed)
    return "must have the table's grid and alpha bins and another seed";
  auto same = [](double a, double b) { return std::abs(a - b) <= 1e-12 * std::max(1.0, std::abs(a)); };
  if (!same(heldout.medium.tau(), table.medium.tau()) || !same(heldout.medium.albedo(), table.medium.albedo()) ||
      !same(heldout.medium.g, table.medium.g) || heldout.max_scatter != table.max_scatter)
    return "must be a table of the same medium (tau, albedo, g, --max-scatter)";
  return "";
}

Certificate certify(const StfModel& model, const Table& fit, const Table& h,
                    const FitSettings& settings) {
  if (fit.alpha_bins != h.alpha_bins || fit.grid != h.grid)
    throw std::invalid_argument("the held-out table's resolution differs from the fit table's");
  std::unique_ptr<DirectionGrid> grid = make_grid(h.grid);
  const BinnedModel binned(model, h, *grid);
  const QuadratureLevels levels(*grid);
  const std::vector<double> x = h.weight(), fit_counts = fit.weight();
  double n = 0, n_fit = 0;
  for (double v : x) n += v;
  for (double v : fit_counts) n_fit += v;
  const std::vector<double> t = normalised(fit_counts);
  const Certificate no_bound{std::numeric_limits<double>::infinity()};
  if (n < 2 || n_fit < 1) return no_bound;  // nothing to certify with
  // Below one fit-table escape a cell's weight says nothing; a floor there keeps single
  // held-out escapes in cells the model calls empty from dominating the variance.
  const double floor = 1 / n_fit;
  const std::vector<std::pair<double, std::vector<double>>> in_h = binned_in_parallel(model, binned, levels, settings);
  if (in_h.empty()) return no_bound;  // cancelled
  Certificate cert;
  double chi2_var = 0, weight_sum = 0;
  for (std::size_t a = 0; a < in_h.size(); ++a) {  // every (alpha bin, cell) of h
    const auto& [bin_probability, p] = in_h[a];
    for (std::int64_t c = 0; c < h.cells; ++c) {
      const std::size_t i = a * h.cells + c;
      const double count = x[i], y = count / n, m = bin_probability * p[c],
                   w = std::max({m, t[i], floor});
      weight_sum += w;
      // E[(y - m)^2] = (p - m)^2 + p (1 - p) / n; count / n^2 and count (count - 1) /
      // (n^2 (n - 1)) are unbiased for p / n and p^2 / n.
      const double d =
          (y - m) * (y - m) - count / (n * n) + count * (count - 1) / (n * n * (n - 1));
      cert.chi2 += d / w;
      // Poisson: Var = [4 (p - m)^2 p / n + 2 p^2 / n^2] / w^2, with p taken as w (the
      // fit table's and the model's, independent of the held-out noise) and (p - m)^2 as d.
      chi2_var += 4 * std::max(0.0, d) / (n * w) + 2 / (n * n);
    }
  }
  cert.chi2_sd = std::sqrt(chi2_var);
  cert.tv_bound = 0.5 * std::sqrt(std::max(0.0, cert.chi2 + 2 * cert.chi2_sd) * weight_sum);
  return cert;
}

namespace {

ToleranceFit fit_family_to_tolerance(const Table& t, const Table& heldout, double tolerance, const FitSettings& s) {
  ToleranceFit r;
  // Fewest alpha bins, then coarsest grid, each within half the tolerance.
  for (int f = t.alpha_bins; f >= 1; --f)
    if (t.alpha_bins % f == 0 && (f == 1 || coarsening_tv(t, heldout, f, 0) <= tolerance / 2)) {
      r.alpha_factor = f;
      break;
    }
  std::unique_ptr<DirectionGrid> grid = make_grid(t.grid);
  int deepest = 0;
  while (s.kind == ModelKind::kVmf && !grid->coarser(deepest + 1).empty()) ++deepest;
  for (int levels = deepest; levels >= 0; --levels)
    if (levels == 0 || coarsening_tv(t, heldout, 1, levels) <= tolerance / 2) {
      r.grid_levels = levels;
      break;
    }
  r.fitted = coarsen_table(t, r.alpha_factor, r.grid_levels);

  std::vector<int> sizes;
  for (int size : auto_candidates(s.kind))
    if (s.automatic || size < s.size) sizes.push_back(size);
  if (!s.automatic) sizes.push_back(s.size);
  int no_gain = 0;
  for (int size : sizes) {
    FitSettings fs = s;
    fs.automatic = false;
    fs.size = size;
    FitReport report;
    StfModel model = fit_table(r.fitted, fs, &report);
    if (s.run.cancelled()) return r;
    Certificate cert = certify(model, t, heldout, s);
    if (s.run.cancelled()) return r;
    r.attempts.emplace_back(size, cert.tv_bound);
    // Two larger models in a row that do not lower the bound are fitting noise: more paths
    // are needed.
    if (r.attempts.size() > 1 && cert.tv_bound >= r.certificate.tv_bound) {
      if (++no_gain == 2) break;
      continue;
    }
    no_gain = 0;
    r.model = std::move(model), r.report = std::move(report), r.size = size, r.certificate = cert;
    if (cert.tv_bound <= tolerance) {
      r.met = true;
      break;
    }
  }
  return r;
}

}  // namespace

ToleranceFit fit_to_tolerance(const Table& t, const Table& heldout, double tolerance,
                              const FitSettings& s) {
  if (heldout.alpha_bins != t.alpha_bins || heldout.grid != t.grid)
    throw std::invalid_argument("the held-out table's resolution differs from the fit table's");
  ToleranceFit r = fit_family_to_tolerance(t, heldout, tolerance, s);
  if (!s.lifted || r.met || s.run.cancelled()) return r;
  // Lifted lobes stand in for hemispherical ones for their strides' sake (no retries); where
  // they miss the tolerance, the hemispherical lobes are fitted too and the better kept.
  FitSettings hemispherical = s;
  hemispherical.lifted = false, hemispherical.hemispherical = true;
  ToleranceFit h = fit_family_to_tolerance(t, heldout, tolerance, hemispherical);
  if (s.run.cancelled() || !(h.met || h.certificate.tv_bound < r.certificate.tv_bound)) return r;
  h.lifted_bound = r.certificate.tv_bound;
  h.attempts.insert(h.attempts.begin(), r.attempts.begin(), r.attempts.end());
  return h;
}

}  // namespace stf::measure
