#include "fit_table.h"

#include <Eigen/Dense>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <thread>

#include "alpha_marginal.h"
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

namespace {

// Escaped weight per cell of alpha bin b: the full table (half < 0) or one half-table.
std::vector<double> bin_counts(const Table& t, int half, int b) {
  std::vector<double> counts(t.cells);
  for (std::int64_t c = 0; c < t.cells; ++c) {
    std::size_t i = std::size_t(b) * t.cells + c;
    counts[c] = half < 0 ? t.weight_half[0][i] + t.weight_half[1][i] : t.weight_half[half][i];
  }
  // The uncollided escapes are an exact delta (at alpha = 0 along +z), kept apart: fitted as a
  // lobe they became a kappa ~1e7 spike at a cell centre, degrees off +z.
  if (b == 0 && t.uncollided_half[0] >= 0)
    counts[make_grid(t.grid)->cell({0, 0, 1})] -= half < 0 ? t.uncollided_half[0] + t.uncollided_half[1] : t.uncollided_half[half];
  // So are the once-scattered ones: their directions lie on a great circle, which a fitted
  // density can only smear.
  const std::uint64_t first = 2 * std::uint64_t(b) * std::uint64_t(t.cells);
  for (auto it = t.once.lower_bound(first); it != t.once.end() && it->first < first + 2 * std::uint64_t(t.cells); ++it)
    if (half < 0 || int(it->first & 1) == half) counts[(it->first - first) >> 1] -= it->second;
  return counts;
}

double sum(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return s;
}

// Bin b's escapes after two or more collisions, both halves: what a bin's lobes are integrated
// against (the quadrature level of each lobe).
double both_halves(const Table& t, int b) { return sum(bin_counts(t, 0, b)) + sum(bin_counts(t, 1, b)); }

// The angle about y from the exit point's z axis to where escapes with these cell counts head
// on average (their mean direction's azimuth in the x-z plane of the exit point's frame).
double heading(const Table& t, const std::vector<double>& counts) {
  double x = 0, z = 0;
  for (std::int64_t c = 0; c < t.cells; ++c) x += counts[c] * t.direction[c][0], z += counts[c] * t.direction[c][2];
  return std::atan2(x, z);
}

// The escapes a fit sees per alpha bin (bin_counts), folded over the mirror symmetry of the
// exit distribution when `image` (mirror_cells) is not empty. Folding bin by bin as the counts
// are read keeps no second copy of the table; it keeps each bin's total.
struct Escapes {
  Escapes(const Table& t, std::vector<std::int64_t> mirror) : table(t), image(std::move(mirror)) {
    for (int b = 0; b < t.alpha_bins; ++b) total.push_back(sum(bin_counts(t, -1, b)));
  }
  const Table& table;
  std::vector<std::int64_t> image;
  std::vector<double> total;  // per bin, both halves
  // How each bin's density turns across it in fits of the whole table (empty: the bins stand
  // still). The half-table fits that choose sizes, pools and blends stand still: turned as well,
  // the models of tau 1 g 0.9 at 1e5 paths came out farther (five seeds: 0.0123 against 0.0119).
  std::vector<BinTurn> turns;
  std::vector<double> counts(int half, int b) const {
    std::vector<double> c = bin_counts(table, half, b);
    if (!image.empty()) fold_over_mirror(c, image);
    return c;
  }
  const BinTurn* turn_of(int half, int b) const { return half < 0 && !turns.empty() ? &turns[std::size_t(b)] : nullptr; }
  // The rates from the headings of the whole table's escapes (alpha_turns), the exit points
  // spread by `tilts` (none: uniform in area).
  void set_turns(const std::vector<double>& tilts) {
    std::vector<double> headings;
    for (int b = 0; b < table.alpha_bins; ++b) headings.push_back(heading(table, counts(-1, b)));
    const std::vector<double> rate = alpha_turns(headings, total, table.alpha_edges);
    for (int b = 0; b < table.alpha_bins; ++b)
      turns.push_back({rate[std::size_t(b)], table.alpha_edges[std::size_t(b)], table.alpha_edges[std::size_t(b) + 1],
                       tilts.empty() ? 0.0 : tilts[std::size_t(b)]});
  }
};

double uncollided_escapes(const Table& t) {
  return t.uncollided_half[0] >= 0 ? t.uncollided_half[0] + t.uncollided_half[1] : 0.0;
}

// Probabilities of the exact parts, per path launched. With the once-scattered escapes tallied
// apart (tables since format 1 with /escape/once_half) both singular parts are known exactly:
// e^{-tau} and the one-collision quadrature; the walk's counts of them are not needed, and only
// the escapes after two or more collisions carry Monte Carlo noise. Older tables give the
// tallied uncollided share and no once-scattered part.
struct SingularParts {
  double uncollided = 0, once = 0;
};
bool singular_parts_exact(const Table& t) { return t.once_tallied && t.uncollided_half[0] >= 0; }
SingularParts singular_parts(const Table& t) {
  if (!singular_parts_exact(t)) return {uncollided_escapes(t) / double(t.paths), 0.0};
  const double tau = t.medium.tau();
  return {std::exp(-tau), t.max_scatter == 0 ? 0.0 : t.medium.albedo() * once_scattered_probability(tau, t.medium.g)};
}

// Probabilities per path of the walk's other outcomes: the escapes after two or more collisions
// (as the factor that turns their tallied count into paths), absorption and truncation. They
// sum to 1 with the exact singular parts. Without exact singular parts, the plain shares.
struct RestProbabilities {
  double fitted_scale = 1, absorbed = 0, truncated = 0;
};

// Absorption estimated with three control variates of known mean (docs/design.md, "Singular
// parts"): the uncollided and the once-scattered indicators (means p0, p1) and
// D = (1 - albedo) c - A over a path of c decided collisions, A its absorption (mean 0: every
// decided collision absorbs with probability 1 - albedo, whatever came before). Their
// covariances with each other and with A follow from the table's totals, the collisions of the
// absorbed paths among them; the regression on all three is the linear estimator of least
// variance, for many paths at most that of A's plain share and of (1 - albedo) c alone. Its
// coefficients come from the same totals as the means they multiply, which biases it by O(1/n)
// (measured about -0.9 / n per path: 9e-6 at 1e5 paths, a fifth of its standard deviation).
// Returns -1 where the table does not tally the absorbed paths' collisions or D is constant
// (albedo 0 or 1).
double absorption_by_regression(const Table& t, const SingularParts& exact) {
  const double n = double(t.paths), a = t.medium.albedo(), pa = t.absorbed_weight / n;
  const double decided = double(t.collisions) - t.truncated_weight;  // a truncated path's last one is not
  const double var_d = a * (1 - a) * decided / n;
  if (t.absorbed_collisions < 0 || !(var_d > 0)) return -1;
  const double p0 = exact.uncollided, p1 = exact.once;
  Eigen::Matrix3d zz;
  zz << p0 * (1 - p0), -p0 * p1, 0,  //
      -p0 * p1, p1 * (1 - p1), (1 - a) * p1,  //
      0, (1 - a) * p1, var_d;
  const Eigen::Vector3d za(-p0 * pa, -p1 * pa, (1 - a) * double(t.absorbed_collisions) / n - pa);
  const Eigen::Vector3d mean(uncollided_escapes(t) / n - p0, t.once_weight() / n - p1,
                             ((1 - a) * decided - t.absorbed_weight) / n);
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(zz);
  if (ldlt.info() != Eigen::Success || !(ldlt.isPositive())) return -1;
  return pa - ldlt.solve(za).dot(mean);
}

// The paths that neither escaped uncollided nor after one collision split among the other
// outcomes independently of how many they were, so each outcome's share of them times the exact
// 1 - p0 - p1 estimates its probability with the singular parts' noise taken out (at tau 1 g 0.9,
// albedo 0.95, the standard deviation of the escapes after two or more collisions halves).
// Absorption then comes from the regression where the table allows it, and the escapes after two
// or more collisions take what is left: with rare absorption (albedo near 1) the collision count
// knows it far better than the absorbed paths do (tau 16, albedo 0.999: a tenth of the standard
// deviation). Where no path is left after the exact parts (tiny tau or tables), nothing tallied
// can carry the rest: it goes to absorption, which is what a renderer makes of a lost path.
RestProbabilities rest_probabilities(const Table& t, const SingularParts& exact) {
  const double n = double(t.paths);
  RestProbabilities r{1.0, t.absorbed_weight / n, t.truncated_weight / n};
  if (!singular_parts_exact(t)) return r;
  const double rest = 1.0 - exact.uncollided - exact.once;
  const double early = uncollided_escapes(t) + t.once_weight();  // the walk's escapes after 0 or 1 collisions
  const double rest_paths = n - early;
  if (!(rest_paths > 0)) return {1.0, std::max(rest, 0.0), 0.0};
  const double share = rest / rest_paths;
  r = {share * n, share * t.absorbed_weight, share * t.truncated_weight};
  const double absorbed = absorption_by_regression(t, exact);
  const double fitted_escapes = t.escaped_weight - early;
  const double fitted = rest - absorbed - r.truncated;
  if (absorbed >= 0 && fitted > 0 && fitted_escapes > 0) r = {fitted * n / fitted_escapes, absorbed, r.truncated};
  return r;
}

// Bins whose status is kBorrowed take the parameters of the nearest fitted bin (the lower
// one on a tie); with no fitted bin at all they become kEmpty with `uniform`.
template <typename P>
void fill_borrowed(std::vector<BinStatus>& status, std::vector<P>& params, const P& uniform) {
  const int bins = int(status.size());
  for (int b = 0; b < bins; ++b) {
    if (status[b] != BinStatus::kBorrowed) continue;
    int source = -1;
    for (int d = 1; d < bins && source < 0; ++d) {
      if (b - d >= 0 && status[b - d] == BinStatus::kFitted) source = b - d;
      else if (b + d < bins && status[b + d] == BinStatus::kFitted) source = b + d;
    }
    if (source < 0) {
      status[b] = BinStatus::kEmpty;
      params[b] = uniform;
    } else {
      params[b] = params[source];
    }
  }
}

// Everything one pass of fitting (on the full table or one half) produces.
struct BinFits {
  const Table* table = nullptr;
  bool hemispherical = false;
  std::vector<BinTurn> turns;  // how the fitted densities turn across their bins (empty: they stand still)
  std::vector<BinStatus> status;
  std::vector<std::vector<VmfLobe>> lobes;  // vmf
  std::vector<std::vector<double>> sh;      // sh: raw projections, not yet smoothed
};

// Whether bin b is sparse enough for its neighbours' escapes to pay (FitSettings::
// pool_neighbours): pooling trades noise for bias, and measured on 1e7-path tables it moved no
// model while its fits took four times as long.
bool worth_pooling(const Escapes& e, int b) { return e.total[std::size_t(b)] < kPoolBelowEscapes; }

// Whether a half-table holds too few of bin b's escapes for `size` lobes (kEscapesPerLobe each):
// the bin's own escapes, not the family, limit its model whatever its size, so its neighbours'
// are worth reaching farther for (wide_pooling).
bool capped_by_escapes(const Escapes& e, int b, int size) {
  return e.total[std::size_t(b)] < 2 * kEscapesPerLobe * size;
}

// Whether bin b is noisy enough for a sloped pool (PoolTry) to be worth its cost: fewer than
// kSlopedPoolEscapesPerLobe escapes per lobe of the chosen size.
bool noisy(const Escapes& e, int b, int size) {
  return worth_pooling(e, b) && e.total[std::size_t(b)] < kSlopedPoolEscapesPerLobe * size;
}

}  // namespace

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

namespace {

// Which bins a pass of fit_bins pools, and how (PoolTry): bin b with the bins within its width
// on either side (0: alone). Bins of width 0 copy their lobes from `others` when given (fitted
// alone or chosen before, at the same size on the same half). A `trial` pass only ranks pools
// for wide_pooling: its pooled fits stop after kPoolTryIterations.
struct Pooling {
  std::vector<PoolTry> bin;
  const BinFits* others = nullptr;
  bool trial = false;
  bool any() const { return std::any_of(bin.begin(), bin.end(), [](const PoolTry& p) { return p.width > 0; }); }
  PoolTry of(int b) const { return bin.empty() ? PoolTry{} : bin[std::size_t(b)]; }
};

// `start`: fits (on a half-table, of this size or smaller) to start the lobes from, or null;
// missing lobes come from splitting the heaviest ones (grow_lobes). `pool` (vmf): a bin of
// width w > 0 has its lobes fitted to its own escapes and, with weights pool_weight(w, d), to
// those of the bins d <= w away, expected where the bin's go turned about y by the difference of
// their headings (the forward peak turns with the exit point: docs/fit.md, "Neighbour
// pooling"), and continued linearly in alpha where the pool is sloped; it gets a lobe per
// kEscapesPerLobe of all the escapes so weighted.
BinFits fit_bins(const Escapes& e, int half, ModelKind kind, int size, const QuadratureLevels& levels,
                 const ShProjector* projector, const FitSettings& s, const BinFits* start = nullptr,
                 const Pooling* pool = nullptr) {
  const Table& t = e.table;
  BinFits fits;
  fits.table = &t;
  fits.hemispherical = kind == ModelKind::kVmf && s.hemispherical;
  if (half < 0) fits.turns = e.turns;
  fits.status.assign(t.alpha_bins, BinStatus::kBorrowed);
  fits.lobes.resize(t.alpha_bins);
  fits.sh.resize(t.alpha_bins);
  // Pooled fits read every bin's escapes (as neighbours); the others each bin's as it is fitted.
  std::vector<std::vector<double>> all;
  std::vector<double> headings, totals;
  for (int b = 0; b < t.alpha_bins && pool && pool->any(); ++b) {
    all.push_back(e.counts(half, b));
    headings.push_back(heading(t, all.back()));
    totals.push_back(sum(all.back()));
  }
  const std::vector<double> smoothed = headings.empty() ? headings : smooth_headings(headings, totals);
  const std::vector<double>& edges = t.alpha_edges;
  auto outward_of = [&](int b) {
    return s.hemispherical ? outward_factors(levels, edges[std::size_t(b)], edges[std::size_t(b) + 1]) : OutwardFactors{};
  };
  // A pooled bin reads its neighbours' outward factors too (up to 8 of them): each bin's are
  // computed once for the pass where they fit in kOutwardCacheBytes (they were 7% of a pooled
  // fit's time), else again for every bin that reads them.
  std::vector<OutwardFactors> outward_cache;
  double points = 0;  // per bin: a factor at every point of every level
  for (int level = 0; level <= QuadratureLevels::kMaxLevel; ++level) points += double(levels.at(level).point.size());
  const double cache_bytes = double(t.alpha_bins) * points * sizeof(double);
  if (s.hemispherical && kind == ModelKind::kVmf && !all.empty() && cache_bytes <= kOutwardCacheBytes) {
    outward_cache.resize(std::size_t(t.alpha_bins));
    for_each_bin(t.alpha_bins, s, [&](int b) { outward_cache[std::size_t(b)] = outward_of(b); });
  }
  auto outward_for = [&](int b, OutwardFactors& own) -> const OutwardFactors& {
    return outward_cache.empty() ? (own = outward_of(b)) : outward_cache[std::size_t(b)];
  };
  for_each_bin(t.alpha_bins, s, [&](int b) {
    std::vector<double> own;
    const std::vector<double>& counts = all.empty() ? (own = e.counts(half, b)) : all[std::size_t(b)];
    double n = sum(counts);
    if (n < s.min_escapes) return;
    fits.status[b] = BinStatus::kFitted;
    if (kind == ModelKind::kSh) {
      fits.sh[b] = projector->project(counts);
      return;
    }
    const PoolTry how = pool ? pool->of(b) : PoolTry{};
    const int width = how.width;
    const bool pooled = width > 0;
    if (pool && !pooled && pool->others && pool->others->status[b] == BinStatus::kFitted) {
      fits.lobes[b] = pool->others->lobes[b];  // fitted before, at this size, on this half
      return;
    }
    const bool warm = start && start->status[b] == BinStatus::kFitted;
    VmfFitOptions options;
    OutwardFactors own_outward;
    const OutwardFactors& outward = outward_for(b, own_outward);
    if (s.hemispherical) options.outward = &outward;
    options.turn = e.turn_of(half, b);
    std::vector<OutwardFactors> near(2 * std::size_t(width));
    double weighted = n;  // the escapes the lobes are fitted to, neighbours' by their weights
    for (int side = 0; side < 2 * width; ++side) {
      const int d = side / 2 + 1, j = side % 2 ? b + d : b - d;
      if (j < 0 || j >= t.alpha_bins || totals[std::size_t(j)] < s.min_escapes) continue;
      const OutwardFactors& neighbour = outward_for(j, near[std::size_t(side)]);
      const double w = pool_weight(width, d);
      // Sloped pools turn by the smoothed headings: their turn slopes carry the heading's change
      // across the pool, and each neighbour's own noisy heading would only add noise to it.
      // Flat pools turn each neighbour onto the bin's heading by its own (docs/fit.md,
      // "Pools chosen bin by bin").
      const std::vector<double>& turn = how.sloped ? smoothed : headings;
      options.pooled.push_back({&all[std::size_t(j)], s.hemispherical ? &neighbour : nullptr,
                                turn[std::size_t(j)] - turn[std::size_t(b)], w, j - b, e.turn_of(half, j)});
      weighted += w * totals[std::size_t(j)];
    }
    // No more lobes than the escapes can support.
    const int lobes = std::clamp(int(weighted / kEscapesPerLobe), 1, size);
    options.sloped = how.sloped;
    // The final fit starts from the half-table fit of its size, already within the noise of
    // its optimum: it stops at 1e-4 (a few tenths of a unit of deviance). Fits that start from
    // split lobes or from k-means need the default 1e-5: slow progress there is not the end
    // (at 1e-4 the half-table vmf:8 of a 1e7-path tau 4.5 table stopped 29000 units of held-out
    // NLL short of its fit at 1e-5).
    VmfFitOptions refine = options;
    if (warm && half < 0) refine.function_tolerance = 1e-4;
    // Trial pools only rank the pools of each bin (wide_pooling); the final fit starts from the
    // winner and runs to convergence. Each try evaluates up to 9 bins' deviances; capped, tau 1
    // g 0.9 at 1e5 paths takes about 4 s a fit instead of 6.4 s, the model at TV 0.0123 from the
    // reference against 0.0121 (at 10 iterations: 0.0152).
    if (pooled && pool->trial) refine.max_iterations = kPoolTryIterations;
    VmfFitResult fit = warm ? fit_vmf_from(counts, levels, grow_lobes(start->lobes[b], lobes), refine)
                            : fit_vmf(counts, levels, lobes, options);
    // A fit pooled with the nearest neighbours alone also starts afresh on the full table and
    // keeps the better optimum: from a pooled half-table fit it often stays in that half's local
    // optimum (pooling is chosen where the tables are small and noisy, so the second fit is
    // cheap). Wider pools hold several times the bin's own escapes, so their half-table fit is
    // already a good start, and a fresh fit against up to 8 neighbours is not cheap (measured
    // with pools within 8: the final fit of tau 1 g 0.9 at 1e5 paths took 9.3 s with it, 2.8 s
    // without, and the model came no closer to the reference).
    if (warm && half < 0 && width == 1) {
      VmfFitResult fresh = fit_vmf(counts, levels, lobes, options);
      if (fresh.deviance < fit.deviance) fit = std::move(fresh);
    }
    fits.lobes[b] = std::move(fit.lobes);
    fits.lobes[b].resize(size, VmfLobe{0, 0, {0, 0, 1}});
  });
  if (kind == ModelKind::kVmf) {
    std::vector<VmfLobe> uniform(size, VmfLobe{0, 0, {0, 0, 1}});
    uniform[0].weight = 1;  // kappa 0: the uniform density
    fill_borrowed(fits.status, fits.lobes, uniform);
  } else {
    std::vector<double> uniform_sh(sh_count(size), 0.0);  // sh:0 has the constant alone
    uniform_sh[0] = 1 / std::sqrt(4 * kPi);
    fill_borrowed(fits.status, fits.sh, uniform_sh);
  }
  return fits;
}

// Cell probabilities of vMF lobes of `fits`' kind in a bin of edges [a0, a1] that stands still:
// hemispherical lobes times the edges' outward factor.
std::vector<double> lobe_cells(const BinFits& fits, const std::vector<VmfLobe>& lobes, const QuadratureLevels& levels,
                               double escapes, double a0, double a1) {
  if (!fits.hemispherical) return vmf_cell_probabilities(lobes, levels, escapes);
  const OutwardFactors outward = outward_factors(levels, a0, a1);
  return vmf_cell_probabilities(lobes, levels, escapes, &outward);
}

// Cell probabilities of bin b under fitted parameters (vMF, or clamped smoothed SH).
std::vector<double> bin_probabilities(const BinFits& fits, int b, ModelKind kind, int size, const ShSmoothing& t,
                                      const QuadratureLevels& levels, const std::vector<double>& sh_basis) {
  if (kind == ModelKind::kVmf) {
    const double escapes = both_halves(*fits.table, b);
    const std::vector<double>& edges = fits.table->alpha_edges;
    if (fits.turns.empty()) return lobe_cells(fits, fits.lobes[b], levels, escapes, edges[std::size_t(b)], edges[std::size_t(b) + 1]);
    const OutwardFactors outward =
        fits.hemispherical ? outward_factors(levels, edges[std::size_t(b)], edges[std::size_t(b) + 1]) : OutwardFactors{};
    return vmf_bin_probabilities(fits.lobes[b], levels, escapes, fits.hemispherical ? &outward : nullptr,
                                 fits.turns[std::size_t(b)]);
  }
  std::vector<double> c = fits.sh[b];
  smooth_sh(c, size, t);
  return clamped_sh_cell_probabilities(c, sh_basis, levels.at(1));
}

// Held-out negative log-likelihood of half `half` under probabilities per bin, with p mixed
// 1e-6 with the uniform density so that a cell the model calls empty costs a finite amount.
struct HeldOut {
  double nll = 0;
  std::vector<double> bin_nll;             // per bin; they sum to nll
  std::vector<std::vector<double>> log_p;  // per bin, per cell
};

HeldOut score(const Escapes& e, int half, const std::vector<std::vector<double>>& p) {
  const Table& t = e.table;
  HeldOut h;
  h.log_p.resize(t.alpha_bins);
  h.bin_nll.assign(t.alpha_bins, 0.0);
  for (int b = 0; b < t.alpha_bins; ++b) {
    std::vector<double> counts = e.counts(half, b);
    h.log_p[b].resize(t.cells);
    for (std::int64_t c = 0; c < t.cells; ++c) {
      double q = (1 - 1e-6) * p[b][c] + 1e-6 * t.solid_angle[c] / (4 * kPi);
      h.log_p[b][c] = std::log(q);
      h.bin_nll[b] -= counts[c] * h.log_p[b][c];
    }
    h.nll += h.bin_nll[b];
  }
  return h;
}

// Standard error of the held-out NLL difference between two models: the paths are independent,
// so its variance is the sum over bins of the multinomial variance of sum n_c d_c.
double difference_error(const Escapes& e, int half, const HeldOut& a, const HeldOut& b) {
  const Table& t = e.table;
  double var = 0;
  for (int bin = 0; bin < t.alpha_bins; ++bin) {
    std::vector<double> counts = e.counts(half, bin);
    double n = sum(counts), s1 = 0, s2 = 0;
    for (std::int64_t c = 0; c < t.cells; ++c) {
      double d = a.log_p[bin][c] - b.log_p[bin][c];
      s1 += counts[c] * d;
      s2 += counts[c] * d * d;
    }
    if (n > 0) var += s2 - s1 * s1 / n;
  }
  return std::sqrt(std::max(var, 0.0));
}

// SH smoothings tried on held-out data: with and without the Lanczos window, times heat
// kernels from none to strong. A plain projection (no window, t = 0) is one of them, so a
// fit is never forced to smooth more than the data want.
std::vector<ShSmoothing> sh_smoothings() {
  std::vector<ShSmoothing> out;
  for (bool lanczos : {false, true})
    for (double t : {0.0, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 1e-1}) out.push_back({lanczos, t});
  return out;
}

// Fits on half 0, scores on half 1. For SH, also picks the smoothing with the lowest held-out
// NLL; returns it in `best_t`, and the fits in `fitted`. vMF lobes start from the fits of the
// next smaller candidate when there are any; `pool` as fit_bins.
HeldOut heldout_for_size(const Escapes& e, const FitSettings& s, int size, const DirectionGrid& grid,
                         const QuadratureLevels& levels, ShSmoothing& best_t, BinFits& fitted,
                         const BinFits* smaller, const Pooling* pool = nullptr) {
  std::unique_ptr<ShProjector> projector;
  std::vector<double> basis;
  if (s.kind == ModelKind::kSh) {
    projector = std::make_unique<ShProjector>(grid, size);
    basis = sh_basis_at(levels.at(1), size);
  }
  BinFits& fits = fitted = fit_bins(e, 0, s.kind, size, levels, projector.get(), s, smaller, pool);
  const Table& t = e.table;
  HeldOut best;
  best_t = {};
  if (cancelled(s)) return best;  // bins were skipped: nothing to score
  for (const ShSmoothing& smoothing : s.kind == ModelKind::kSh ? sh_smoothings() : std::vector<ShSmoothing>{{}}) {
    std::vector<std::vector<double>> p(t.alpha_bins);
    for_each_bin(t.alpha_bins, s,
                 [&](int b) { p[b] = bin_probabilities(fits, b, s.kind, size, smoothing, levels, basis); });
    if (cancelled(s)) return {};  // some bins were skipped
    HeldOut h = score(e, 1, p);
    if (best.log_p.empty() || h.nll < best.nll) best = std::move(h), best_t = smoothing;
  }
  return best;
}

// Neighbour pooling adds no parameter but a bias (the neighbours' escapes are not quite the
// bin's turned), so it can only pay where noise, not the family, limits the model: where the
// held-out NLL stopped falling before the largest size (`best`, an index into the `sizes`
// tried), and in bins with few escapes (worth_pooling). Then the chosen size and the next are
// fitted pooled on half 0 (the other bins as fitted alone); a pooled fit replaces the choice
// (`size`, its half-0 `fits` and `score`) when its held-out NLL is lower (the rule of the
// sizes). Returns each bin's pool: the nearest neighbours in the bins worth pooling when pooling
// won, else none.
std::vector<PoolTry> choose_pooling(const Escapes& e, const FitSettings& s, const DirectionGrid& grid,
                                    const QuadratureLevels& levels, const std::vector<int>& sizes,
                                    const std::vector<BinFits>& half_fits, std::size_t best, int& size,
                                    BinFits& fits, HeldOut& score, FitReport& r) {
  const std::vector<int> all = auto_candidates(s.kind);
  std::vector<PoolTry> alone(std::size_t(e.table.alpha_bins)), nearest = alone;
  for (int b = 0; b < e.table.alpha_bins; ++b) nearest[std::size_t(b)].width = worth_pooling(e, b) ? 1 : 0;
  if (nearest == alone || best + 1 >= all.size()) return alone;
  const auto next = std::upper_bound(all.begin(), all.end(), size);
  std::vector<PoolTry> chosen = alone;
  r.pool_heldout_nll.push_back(score.nll);
  for (int candidate : next == all.end() ? std::vector<int>{size} : std::vector<int>{size, *next}) {
    const auto tried = std::find(sizes.begin(), sizes.end(), candidate);
    const Pooling pool{nearest, tried == sizes.end() ? nullptr : &half_fits[std::size_t(tried - sizes.begin())]};
    ShSmoothing unused;
    BinFits pooled;
    HeldOut h = heldout_for_size(e, s, candidate, grid, levels, unused, pooled, &fits, &pool);
    if (cancelled(s)) return alone;
    r.pool_sizes.push_back(candidate);
    r.pool_heldout_nll.push_back(h.nll);
    if (h.nll < score.nll) {
      size = candidate, chosen = nearest;
      fits = std::move(pooled), score = std::move(h);
    }
  }
  r.neighbour_weight = chosen == alone ? 0 : kNeighbourWeight;
  return chosen;
}

// What a pass of pools gains in each bin it tries: the held-out NLL the pooled fits save against
// the choice so far, in the bin and, weighted kNeighbourGainWeight, in its two neighbours where
// they tried the same pool. A bin's own gain is one noisy score of a few hundred escapes, and
// the best of such scores fits the held-out half; neighbouring bins differ little, so their
// gains say something of this bin's (tau 1 g 0.9 at 1e5 paths, five seeds: mean 0.0124 against
// 0.0127 on the bin's own gain alone; neighbours within 2 at 1/4 further: no change).
constexpr double kNeighbourGainWeight = 0.5;
std::vector<double> pooled_gain(const Pooling& pool, const HeldOut& before, const HeldOut& pooled) {
  const int bins = int(pool.bin.size());
  std::vector<double> gain(std::size_t(bins), 0.0);
  for (int b = 0; b < bins; ++b)
    for (int j = std::max(0, b - 1); j <= std::min(bins - 1, b + 1); ++j)
      if (pool.bin[std::size_t(j)].width > 0)
        gain[std::size_t(b)] += (j == b ? 1.0 : kNeighbourGainWeight) *
                                (before.bin_nll[std::size_t(j)] - pooled.bin_nll[std::size_t(j)]);
  return gain;
}

// Wider pools (kPoolTries), fitted on half 0 in the bins they are tried in: sloped ones in the
// noisy bins, where the lobes change their shape from bin to bin faster than the noise hides;
// flat ones where the half-table escapes cannot carry the chosen size (capped_by_escapes),
// whatever the family, and the exit distribution changes slowly with alpha. Each bin keeps a
// pool where it gains held-out NLL over the choice so far (pooled_gain: its own escapes and,
// at half weight, its neighbours'). `pools`,
// `fits` and `score` (the choice so far, on half 0) are updated bin by bin.
void wide_pooling(const Escapes& e, const FitSettings& s, const DirectionGrid& grid, const QuadratureLevels& levels,
                  int size, std::vector<PoolTry>& pools, BinFits& fits, HeldOut& score) {
  const int bins = e.table.alpha_bins;
  for (const PoolTry& tried : kPoolTries) {
    Pooling pool{std::vector<PoolTry>(std::size_t(bins)), &fits, true};
    for (int b = 0; b < bins; ++b)
      if ((tried.sloped ? noisy(e, b, size) : capped_by_escapes(e, b, size)) && pools[std::size_t(b)] != tried)
        pool.bin[std::size_t(b)] = tried;
    if (!pool.any()) continue;
    ShSmoothing unused;
    BinFits pooled;
    HeldOut h = heldout_for_size(e, s, size, grid, levels, unused, pooled, &fits, &pool);
    if (cancelled(s)) return;
    const std::vector<double> gain = pooled_gain(pool, score, h);
    for (int b = 0; b < bins; ++b) {
      if (pool.bin[std::size_t(b)].width == 0 || !(gain[std::size_t(b)] > 0)) continue;
      pools[std::size_t(b)] = tried;
      fits.lobes[std::size_t(b)] = std::move(pooled.lobes[std::size_t(b)]);
      score.nll += h.bin_nll[std::size_t(b)] - score.bin_nll[std::size_t(b)];
      score.bin_nll[std::size_t(b)] = h.bin_nll[std::size_t(b)];
      score.log_p[std::size_t(b)] = std::move(h.log_p[std::size_t(b)]);
    }
  }
}

// Held-out NLL of the half-0 fits behind `flat` (its per-bin cell log-probabilities) with each
// bin's density blended as a model of each width 0 .. max_width blends it (tilts from half 0),
// and the width chosen; in turning models (`turned`) each neighbour's density as the sampler
// turns it into the bin. Blending adds no parameter, but a width is kept only where its held-out
// gain over none exceeds kBlendStandardErrors standard errors: in models whose bins stood still,
// the forward peak near the axis turns with alpha and a mixture of neighbours broadens it, which
// the held-out NLL, summed over all bins, could miss by a nat or two while TV grew (tau 1 g 0.9
// at 1e5 paths, seed 4: blend 1 ahead by 1.1 standard errors, TV 0.0165 with it, 0.0133
// without). Among the widths so kept the lowest NLL wins.
constexpr double kBlendStandardErrors = 2;

// Each bin's half-table lobes (standing still) as a turning model blends them into the bins
// within `width` of it: bin j in bin b turned by bin j's rate from j's middle to b's (the middle
// of the exit angles the blend spreads it over), hemispherical lobes with bin j's outward factor
// turned with them, as the sampler turns them. Scored at their own bin instead, a neighbour's
// peak lies a bin's turn away (6 degrees near the axis at tau 1 g 0.9), and the held-out half
// called blends worse that bring the model closer to the reference (docs/fit.md, "Blends of
// turning bins"). Each pair once, the bins in parallel.
struct TurnedNeighbours {
  int width = 0;
  std::vector<std::vector<std::vector<double>>> cells;  // [b][j - b + width]
  const std::vector<double>& at(int j, int b) const { return cells[std::size_t(b)][std::size_t(j - b + width)]; }
};
TurnedNeighbours turned_neighbours(const BinFits& fits, const std::vector<BinTurn>& turns, const QuadratureLevels& levels,
                                   int width, const FitSettings& s) {
  const Table& t = *fits.table;
  const std::vector<double>& edges = t.alpha_edges;
  auto middle = [&](int bin) { return 0.5 * (edges[std::size_t(bin)] + edges[std::size_t(bin) + 1]); };
  TurnedNeighbours n{width, std::vector<std::vector<std::vector<double>>>(
                                std::size_t(t.alpha_bins), std::vector<std::vector<double>>(2 * std::size_t(width) + 1))};
  for_each_bin(t.alpha_bins, s, [&](int b) {
    for (int j = std::max(0, b - width); j <= std::min(t.alpha_bins - 1, b + width); ++j) {
      if (j == b) continue;
      const double angle = turns[std::size_t(j)].rate * (middle(b) - middle(j));
      std::vector<VmfLobe> lobes = fits.lobes[std::size_t(j)];
      for (VmfLobe& l : lobes) l.mean = turn_about_y(l.mean, angle);
      n.cells[std::size_t(b)][std::size_t(j - b + width)] = lobe_cells(
          fits, lobes, levels, both_halves(t, j), edges[std::size_t(j)] + angle, edges[std::size_t(j) + 1] + angle);
    }
  });
  return n;
}

struct BlendChoice {
  std::vector<double> nll, error;  // per width 0 .. max_width: held-out NLL, its SE against width 0
  int width = 0;                   // one for every bin
  std::vector<int> widths;         // per bin; empty: none
  double by_bin_gain = 0, by_bin_error = 0;  // the widths by bin against one width: held-out gain, SE
};

// Widths by bin: each bin takes the width whose held-out gain over none, summed over the bins
// within kBlendReach at hat weights 1 - |j - b| / (kBlendReach + 1), is largest (none where no
// width gains). A bin's own gain is the score of a few hundred escapes; its neighbours' say
// what a bin's cannot (tau 1 g 0.9 at 1e5 paths, five seeds: mean 0.0110 at reach 3, 0.0109 at
// reach 1 but 1-3% farther than one width on media where the widest suits every bin).
constexpr int kBlendReach = 3;
std::vector<int> widths_by_bin(const std::vector<HeldOut>& blended) {
  const int bins = int(blended[0].bin_nll.size());
  std::vector<int> widths(std::size_t(bins), 0);
  for (int b = 0; b < bins; ++b) {
    double best = 0;
    for (std::size_t w = 1; w < blended.size(); ++w) {
      double gain = 0;
      for (int j = std::max(0, b - kBlendReach); j <= std::min(bins - 1, b + kBlendReach); ++j)
        gain += (1 - double(std::abs(j - b)) / (kBlendReach + 1)) *
                (blended[0].bin_nll[std::size_t(j)] - blended[w].bin_nll[std::size_t(j)]);
      if (gain > best) best = gain, widths[std::size_t(b)] = int(w);
    }
  }
  return widths;
}

// The held-out scores of a model whose bin b is blended at widths[b].
HeldOut scores_at_widths(const std::vector<HeldOut>& blended, const std::vector<int>& widths) {
  HeldOut h;
  for (std::size_t b = 0; b < widths.size(); ++b) {
    const HeldOut& at = blended[std::size_t(widths[b])];
    h.bin_nll.push_back(at.bin_nll[b]);
    h.nll += at.bin_nll[b];
    h.log_p.push_back(at.log_p[b]);
  }
  return h;
}

// One width for every bin, and widths by bin where they gain over it by more than
// kBlendStandardErrors standard errors (the widths are chosen on the half that scores them, so
// a small gain is their selection's). Near the axis of a forward medium the density changes
// its shape from bin to bin and wants a narrow blend, far from it the bins are noisy and want
// the widest: tau 1 g 0.9 at 1e5 paths, five seeds, mean joint TV 0.0114 with one width, 0.0110
// by bin; where the widest suits every bin the gain stays within noise and one width is kept.
BlendChoice choose_blend(const Escapes& e, const HeldOut& flat, int max_width, const TurnedNeighbours& turned) {
  const Table& t = e.table;
  StfModel shape;
  shape.alpha_probability.assign(std::size_t(t.alpha_bins), 0.0);
  shape.alpha_tilt = fit_alpha_tilts(t, 0);
  std::vector<std::vector<double>> p(t.alpha_bins), q(t.alpha_bins);
  for (int b = 0; b < t.alpha_bins; ++b)
    for (double l : flat.log_p[b]) p[b].push_back(std::exp(l));
  BlendChoice c;
  c.nll = {flat.nll}, c.error = {0.0};
  std::vector<HeldOut> blended{flat};
  for (shape.alpha_blend = 1; shape.alpha_blend <= max_width; ++shape.alpha_blend) {
    for (int b = 0; b < t.alpha_bins; ++b)
      q[b] = blended_cells(shape, b, [&](int j) -> const std::vector<double>& {
        return j == b || turned.cells.empty() ? p[std::size_t(j)] : turned.at(j, b);
      });
    blended.push_back(score(e, 1, q));
    c.nll.push_back(blended.back().nll);
    c.error.push_back(difference_error(e, 1, blended.back(), flat));
  }
  for (int w = 1; w <= max_width; ++w)
    if (c.nll[std::size_t(w)] < c.nll[std::size_t(c.width)] && c.nll[0] - c.nll[std::size_t(w)] > kBlendStandardErrors * c.error[std::size_t(w)])
      c.width = w;
  const std::vector<int> one(std::size_t(t.alpha_bins), c.width), by_bin = widths_by_bin(blended);
  const HeldOut at_one = scores_at_widths(blended, one), at_by_bin = scores_at_widths(blended, by_bin);
  c.by_bin_gain = at_one.nll - at_by_bin.nll;
  c.by_bin_error = difference_error(e, 1, at_by_bin, at_one);
  const std::vector<int>& widths = c.by_bin_gain > kBlendStandardErrors * c.by_bin_error ? by_bin : one;
  if (std::any_of(widths.begin(), widths.end(), [](int h) { return h > 0; })) c.widths = widths;
  return c;
}

// Area-uniform alpha marginal: for a model of nothing escaping.
std::vector<double> uniform_alpha(const std::vector<double>& edges) {
  std::vector<double> p(edges.size() - 1);
  for (std::size_t b = 0; b + 1 < edges.size(); ++b) p[b] = 0.5 * (std::cos(edges[b]) - std::cos(edges[b + 1]));
  return p;
}

}  // namespace

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
  if (s.automatic || s.kind == ModelKind::kSh) {
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
      // took up to 12 s (docs/fit.md, "Pools chosen bin by bin").
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
  r.pools = pool.bin;
  r.smoothing = smoothing.t;
  r.alpha_penalty = marginal.bin_escapes.empty() ? -1 : marginal.penalty;
  r.lanczos_window = smoothing.lanczos;
  r.fit_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return m;
}

}  // namespace stf::fit
