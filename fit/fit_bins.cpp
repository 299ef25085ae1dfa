// One pass of fitting every alpha bin, pooled or not (fit_stages.h).
#include "fit_stages.h"

namespace stf::fit::stages {

BinFits fit_bins(const Escapes& e, int half, ModelKind kind, int size, const QuadratureLevels& levels,
                 const ShProjector* projector, const FitSettings& s, const BinFits* start,
                 const Pooling* pool) {
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
      // Flat pools turn each neighbour onto the bin's heading by its own (docs/studies/2026-12-fit-measurements.md,
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

std::vector<double> lobe_cells(const BinFits& fits, const std::vector<VmfLobe>& lobes, const QuadratureLevels& levels,
                               double escapes, double a0, double a1) {
  if (!fits.hemispherical) return vmf_cell_probabilities(lobes, levels, escapes);
  const OutwardFactors outward = outward_factors(levels, a0, a1);
  return vmf_cell_probabilities(lobes, levels, escapes, &outward);
}

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

}  // namespace stf::fit::stages
