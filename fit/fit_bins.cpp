// One pass of fitting every alpha bin, pooled or not (fit_stages.h).
#include "fit_stages.h"

namespace stf::fit::stages {

namespace {

// What a pooled pass reads of every bin: its escapes (as neighbours), its heading and its total,
// and the headings smoothed across alpha.
struct Neighbourhood {
  std::vector<std::vector<double>> counts;
  std::vector<double> headings, totals, smoothed;

  Neighbourhood(const Escapes& e, const Pass& pass) {
    const Table& t = e.table;
    for (int b = 0; b < t.alpha_bins && pass.pool && pass.pool->any(); ++b) {
      counts.push_back(e.counts(pass.half, b));
      headings.push_back(heading(t, counts.back()));
      totals.push_back(sum(counts.back()));
    }
    smoothed = headings.empty() ? headings : smooth_headings(headings, totals);
  }
};

// Each bin's outward factors for hemispherical lobes. A pooled bin reads its neighbours' too
// (up to 8 of them): each bin's are computed once for the pass where they fit in
// kConfig.outward_cache_bytes (they were 7% of a pooled fit's time), else again for every bin that reads
// them.
class OutwardSource {
 public:
  OutwardSource(const Table& t, const QuadratureLevels& levels, const FitSettings& s, bool pooled)
      : t_(t), levels_(levels) {
    double points = 0;  // per bin: a factor at every point of every level
    for (int level = 0; level <= QuadratureLevels::kMaxLevel; ++level) points += double(levels.at(level).point.size());
    const double cache_bytes = double(t.alpha_bins) * points * sizeof(double);
    if (!s.hemispherical || s.kind != ModelKind::kVmf || !pooled || cache_bytes > kConfig.outward_cache_bytes) return;
    cache_.resize(std::size_t(t.alpha_bins));
    for_each_bin(t.alpha_bins, s, "outward factors", [&](int b) { cache_[std::size_t(b)] = compute(b); });
  }
  // Bin b's factors (hemispherical lobes only): from the cache, or computed into `own`.
  const OutwardFactors& of(int b, OutwardFactors& own) const {
    return cache_.empty() ? (own = compute(b)) : cache_[std::size_t(b)];
  }

 private:
  OutwardFactors compute(int b) const {
    return outward_factors(levels_, t_.alpha_edges[std::size_t(b)], t_.alpha_edges[std::size_t(b) + 1]);
  }
  const Table& t_;
  const QuadratureLevels& levels_;
  std::vector<OutwardFactors> cache_;
};

// What every bin of a pass reads.
struct PassContext {
  const Escapes& e;
  const Pass& pass;
  const Neighbourhood& n;
  const OutwardSource& outward;
  int min_escapes;
};

// Bin b's neighbours in its pool, added to `options`; returns the escapes the lobes are fitted
// to: the bin's own (`escapes`) and the neighbours' by their weights. `near` holds the
// neighbours' factors computed for this bin.
double add_pool(const PassContext& c, int b, double escapes, VmfFitOptions& options, std::vector<OutwardFactors>& near) {
  const PoolTry how = c.pass.pool ? c.pass.pool->of(b) : PoolTry{};
  const int width = how.width, bins = c.e.table.alpha_bins;
  const Neighbourhood& n = c.n;
  near.resize(2 * std::size_t(width));
  double weighted = escapes;
  for (int side = 0; side < 2 * width; ++side) {
    const int d = side / 2 + 1, j = side % 2 ? b + d : b - d;
    if (j < 0 || j >= bins || n.totals[std::size_t(j)] < c.min_escapes) continue;
    const double w = pool_weight(width, d);
    // Sloped pools turn by the smoothed headings: their turn slopes carry the heading's change
    // across the pool, and each neighbour's own noisy heading would only add noise to it.
    // Flat pools turn each neighbour onto the bin's heading by its own.
    const std::vector<double>& turn = how.sloped ? n.smoothed : n.headings;
    options.pooled.push_back({&n.counts[std::size_t(j)], options.outward ? &c.outward.of(j, near[std::size_t(side)]) : nullptr,
                              turn[std::size_t(j)] - turn[std::size_t(b)], w, j - b, c.e.turn_of(c.pass.half, j)});
    weighted += w * n.totals[std::size_t(j)];
  }
  options.sloped = how.sloped;
  return weighted;
}

// Bin b's lobes: from the pass's start where it has one (grown to the size), else from k-means.
std::vector<VmfLobe> fit_lobes(const std::vector<double>& counts, const Pass& pass, int b, int lobes,
                               const QuadratureLevels& levels, const VmfFitOptions& options) {
  const bool warm = pass.start && pass.start->status[std::size_t(b)] == BinStatus::kFitted;
  const int width = pass.pool ? pass.pool->of(b).width : 0;
  // The final fit starts from the half-table fit of its size, already within the noise of its
  // optimum: it stops at 1e-4 (a few tenths of a unit of deviance). Fits that start from split
  // lobes or from k-means need the default 1e-5: slow progress there is not the end.
  VmfFitOptions refine = options;
  if (warm && pass.half < 0) refine.function_tolerance = 1e-4;
  // Trial pools only rank the pools of each bin (wide_pooling); the final fit starts from the
  // winner and runs to convergence.
  if (width > 0 && pass.pool->trial) refine.max_iterations = kConfig.pool_try_iterations;
  VmfFitResult fit = warm ? fit_vmf_from(counts, levels, grow_lobes(pass.start->lobes[std::size_t(b)], lobes), refine)
                          : fit_vmf(counts, levels, lobes, options);
  // A fit pooled with the nearest neighbours alone also starts afresh on the full table and
  // keeps the better optimum: from a pooled half-table fit it often stays in that half's local
  // optimum (pooling is chosen where the tables are small and noisy, so the second fit is
  // cheap). Wider pools hold several times the bin's own escapes, so their half-table fit is
  // already a good start, and a fresh fit against up to 8 neighbours is not cheap.
  if (warm && pass.half < 0 && width == 1) {
    VmfFitResult fresh = fit_vmf(counts, levels, lobes, options);
    if (fresh.deviance < fit.deviance) fit = std::move(fresh);
  }
  return std::move(fit.lobes);
}

// What a pass is called in the fit's progress.
std::string pass_name(const Pass& pass) {
  const std::string size = "size " + std::to_string(pass.size);
  if (pass.half < 0) return "final fit, " + size;
  return (pass.pool ? "pooled fits, " : "fits, ") + size + ", half " + std::to_string(pass.half);
}

}  // namespace

BinFits fit_bins(const Escapes& e, const Pass& pass, const QuadratureLevels& levels, const FitSettings& s) {
  const Table& t = e.table;
  BinFits fits;
  fits.table = &t;
  fits.kind = s.kind, fits.size = pass.size;
  fits.hemispherical = s.kind == ModelKind::kVmf && s.hemispherical;
  fits.lifted = s.kind == ModelKind::kVmf && s.lifted;
  if (pass.half < 0) fits.turns = e.turns;
  fits.status.assign(t.alpha_bins, BinStatus::kBorrowed);
  fits.lobes.resize(t.alpha_bins);
  fits.sh.resize(t.alpha_bins);
  // Pooled fits read every bin's escapes (as neighbours); the others each bin's as it is fitted.
  const Neighbourhood n(e, pass);
  const OutwardSource outward(t, levels, s, !n.counts.empty());
  const PassContext context{e, pass, n, outward, s.min_escapes};
  for_each_bin(t.alpha_bins, s, pass_name(pass), [&](int b) {
    std::vector<double> own;
    const std::vector<double>& counts = n.counts.empty() ? (own = e.counts(pass.half, b)) : n.counts[std::size_t(b)];
    const double escapes = sum(counts);
    if (escapes < s.min_escapes) return;
    fits.status[b] = BinStatus::kFitted;
    if (s.kind == ModelKind::kSh) {
      fits.sh[b] = pass.projector->project(counts);
      return;
    }
    const bool pooled = pass.pool && pass.pool->of(b).width > 0;
    if (pass.pool && !pooled && pass.pool->others && pass.pool->others->status[b] == BinStatus::kFitted) {
      fits.lobes[b] = pass.pool->others->lobes[b];  // fitted before, at this size, on this half
      return;
    }
    VmfFitOptions options;
    OutwardFactors own_outward;
    if (s.hemispherical) options.outward = &outward.of(b, own_outward);
    options.turn = e.turn_of(pass.half, b);
    std::vector<OutwardFactors> near;
    const double weighted = add_pool(context, b, escapes, options, near);
    // No more lobes than the escapes can support.
    const int lobes = std::clamp(int(weighted / kConfig.escapes_per_lobe), 1, pass.size);
    fits.lobes[b] = fit_lobes(counts, pass, b, lobes, levels, options);
    fits.lobes[b].resize(pass.size, VmfLobe{0, 0, {0, 0, 1}});
  });
  if (s.kind == ModelKind::kVmf) {
    std::vector<VmfLobe> uniform(pass.size, VmfLobe{0, 0, {0, 0, 1}});
    uniform[0].weight = 1;  // kappa 0: the uniform density
    fill_borrowed(fits.status, fits.lobes, uniform);
  } else {
    std::vector<double> uniform_sh(sh_count(pass.size), 0.0);  // sh:0 has the constant alone
    uniform_sh[0] = 1 / std::sqrt(4 * kPi);
    fill_borrowed(fits.status, fits.sh, uniform_sh);
  }
  return fits;
}

std::vector<double> lobe_cells(const BinFits& fits, const std::vector<VmfLobe>& lobes, const QuadratureLevels& levels,
                               double escapes, const BinTurn& bin, Tails tails) {
  const OutwardFactors outward = fits.hemispherical ? outward_factors(levels, bin.a0, bin.a1) : OutwardFactors{};
  BinTurn moved = bin;
  moved.lifted = fits.lifted;
  return lobe_cell_probabilities(lobes, levels, escapes, fits.hemispherical ? &outward : nullptr,
                                 moved.rate != 0 || moved.lifted ? &moved : nullptr, tails);
}

std::vector<double> bin_probabilities(const BinFits& fits, int b, const ShSmoothing& t, const QuadratureLevels& levels,
                                      const std::vector<double>& sh_basis, Tails tails) {
  if (fits.kind == ModelKind::kVmf) {
    const std::vector<double>& edges = fits.table->alpha_edges;
    const BinTurn bin = fits.turns.empty() ? BinTurn{0, edges[std::size_t(b)], edges[std::size_t(b) + 1], 0}
                                           : fits.turns[std::size_t(b)];
    return lobe_cells(fits, fits.lobes[b], levels, both_halves(*fits.table, b), bin, tails);
  }
  std::vector<double> c = fits.sh[b];
  smooth_sh(c, fits.size, t);
  return clamped_sh_cell_probabilities(c, sh_basis, levels.at(kShScoreLevel));
}

}  // namespace stf::fit::stages
