// Held-out scores, and the model size and pools they choose (fit_stages.h).
#include "fit_stages.h"

namespace stf::fit::stages {

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

std::vector<ShSmoothing> sh_smoothings() {
  std::vector<ShSmoothing> out;
  for (bool lanczos : {false, true})
    for (double t : {0.0, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 1e-1}) out.push_back({lanczos, t});
  return out;
}

HeldOut heldout_for_size(const Escapes& e, const FitSettings& s, int size, const DirectionGrid& grid,
                         const QuadratureLevels& levels, ShSmoothing& best_t, BinFits& fitted,
                         const BinFits* smaller, const Pooling* pool) {
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

}  // namespace stf::fit::stages
