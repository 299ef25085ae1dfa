// What each bin takes from its neighbours: pools and blends (fit_stages.h).
#include "fit_stages.h"

namespace stf::fit::stages {

Neighbours choose_neighbours(const Escapes& e, const FitSettings& s, const DirectionGrid& grid,
                             const QuadratureLevels& levels, SizeChoice& c, FitReport& r) {
  Neighbours n;
  const Table& t = e.table;
  if (!s.automatic) return n;
  if (s.kind == ModelKind::kVmf && s.pool_neighbours && t.alpha_bins > 1) {
    n.pool.bin = choose_pooling(e, s, grid, levels, c, r);
    if (cancelled(s)) return n;
    if (s.hemispherical && s.wide_pools) wide_pooling(e, s, grid, levels, c, n.pool.bin);
    if (cancelled(s)) return n;
  }
  if (t.alpha_bins > 1) {
    TurnedNeighbours turned;
    if (!e.turns.empty() && s.max_blend > 0) turned = turned_neighbours(c.fits, e.turns, levels, s.max_blend, s);
    if (cancelled(s)) return n;
    n.blend_widths = choose_blend(e, c.score, s, turned, r);
  }
  return n;
}

std::vector<PoolTry> choose_pooling(const Escapes& e, const FitSettings& s, const DirectionGrid& grid,
                                    const QuadratureLevels& levels, SizeChoice& c, FitReport& r) {
  const std::vector<int> all = auto_candidates(s.kind);
  std::vector<PoolTry> alone(std::size_t(e.table.alpha_bins)), nearest = alone;
  for (int b = 0; b < e.table.alpha_bins; ++b) nearest[std::size_t(b)].width = worth_pooling(e, b) ? 1 : 0;
  if (nearest == alone || c.best + 1 >= all.size()) return alone;
  std::vector<PoolTry> chosen = alone;
  r.pool_heldout_nll.push_back(c.score.nll);
  for (std::size_t i = c.best; i <= c.best + 1; ++i) {  // the chosen size (all[c.best]) and the next
    const Pooling pool{nearest, i < c.half_fits.size() ? &c.half_fits[i] : nullptr};
    SizeTrial pooled = heldout_for_size(e, s, {-1, all[i], nullptr, &c.fits, &pool}, grid, levels);
    if (cancelled(s)) return alone;
    r.pool_sizes.push_back(all[i]);
    r.pool_heldout_nll.push_back(pooled.score.nll);
    if (pooled.score.nll < c.score.nll) {
      c.size = all[i], chosen = nearest;
      c.fits = std::move(pooled.fits), c.score = std::move(pooled.score);
    }
  }
  r.neighbour_weight = chosen == alone ? 0 : pool_weight(1, 1);
  return chosen;
}

std::vector<double> pooled_gain(const Pooling& pool, const HeldOut& before, const HeldOut& pooled) {
  const int bins = int(pool.bin.size());
  std::vector<double> gain(std::size_t(bins), 0.0);
  for (int b = 0; b < bins; ++b)
    for (int j = std::max(0, b - 1); j <= std::min(bins - 1, b + 1); ++j)
      if (pool.bin[std::size_t(j)].width > 0)
        gain[std::size_t(b)] += (j == b ? 1.0 : kConfig.neighbour_gain_weight) *
                                (before.bin_nll[std::size_t(j)] - pooled.bin_nll[std::size_t(j)]);
  return gain;
}

void wide_pooling(const Escapes& e, const FitSettings& s, const DirectionGrid& grid, const QuadratureLevels& levels,
                  SizeChoice& c, std::vector<PoolTry>& pools) {
  const int bins = e.table.alpha_bins, size = c.size;
  for (const PoolTry& tried : kConfig.pool_tries) {
    Pooling pool{std::vector<PoolTry>(std::size_t(bins)), &c.fits, true};
    for (int b = 0; b < bins; ++b)
      if ((tried.sloped ? noisy(e, b, size) : capped_by_escapes(e, b, size)) && pools[std::size_t(b)] != tried)
        pool.bin[std::size_t(b)] = tried;
    if (!pool.any()) continue;
    SizeTrial trial = heldout_for_size(e, s, {-1, size, nullptr, &c.fits, &pool}, grid, levels);
    if (cancelled(s)) return;
    const std::vector<double> gain = pooled_gain(pool, c.score, trial.score);
    for (std::size_t b = 0; b < std::size_t(bins); ++b) {
      if (pool.bin[b].width == 0 || !(gain[b] > 0)) continue;
      pools[b] = tried;
      c.fits.lobes[b] = std::move(trial.fits.lobes[b]);
      c.score.nll += trial.score.bin_nll[b] - c.score.bin_nll[b];
      c.score.bin_nll[b] = trial.score.bin_nll[b];
      c.score.log_p[b] = std::move(trial.score.log_p[b]);
    }
  }
}

}  // namespace stf::fit::stages
