// Held-out scores, and the model size and pools they choose (fit_stages.h).
#include "fit_stages.h"

#include <limits>

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

SizeTrial heldout_for_size(const Escapes& e, const FitSettings& s, Pass pass, const DirectionGrid& grid,
                           const QuadratureLevels& levels) {
  std::unique_ptr<ShProjector> projector;
  std::vector<double> basis;
  if (s.kind == ModelKind::kSh) {
    projector = std::make_unique<ShProjector>(grid, pass.size);
    basis = sh_basis_at(levels.at(1), pass.size);
  }
  pass.half = 0, pass.projector = projector.get();
  SizeTrial trial;
  trial.fits = fit_bins(e, pass, levels, s);
  const Table& t = e.table;
  if (cancelled(s)) return trial;  // bins were skipped: nothing to score
  for (const ShSmoothing& smoothing : s.kind == ModelKind::kSh ? sh_smoothings() : std::vector<ShSmoothing>{{}}) {
    std::vector<std::vector<double>> p(t.alpha_bins);
    for_each_bin(t.alpha_bins, s, "held-out scores, size " + std::to_string(trial.fits.size),
                 [&](int b) { p[b] = bin_probabilities(trial.fits, b, smoothing, levels, basis, Tails::kCut); });
    if (cancelled(s)) return {};  // some bins were skipped
    HeldOut h = score(e, 1, p);
    if (trial.score.log_p.empty() || h.nll < trial.score.nll) trial.score = std::move(h), trial.smoothing = smoothing;
  }
  return trial;
}

SizeChoice choose_size(const Escapes& e, const FitSettings& s, const DirectionGrid& grid, const QuadratureLevels& levels,
                       FitReport& r) {
  SizeChoice c;
  c.size = s.size;
  // SH chooses its smoothing on the held-out half; evenly split weights have none, and keep the
  // plain projection.
  if (!s.automatic && (s.kind != ModelKind::kSh || e.table.halves == Halves::kEven)) return c;
  std::vector<int> sizes = s.automatic ? auto_candidates(s.kind) : std::vector<int>{s.size};
  std::vector<SizeTrial> trials;
  double lowest = std::numeric_limits<double>::infinity();
  int misses = 0;
  for (int candidate : sizes) {
    trials.push_back(heldout_for_size(e, s, {-1, candidate, nullptr, trials.empty() ? nullptr : &trials.back().fits},
                                      grid, levels));
    if (cancelled(s)) return c;
    if (trials.back().score.nll < lowest) lowest = trials.back().score.nll, misses = 0;
    else if (++misses == 2) break;
  }
  for (std::size_t i = 1; i < trials.size(); ++i)
    if (trials[i].score.nll < trials[c.best].score.nll) c.best = i;
  for (std::size_t i = 0; i < trials.size(); ++i) {
    r.candidates.push_back(sizes[i]);
    r.heldout_nll.push_back(trials[i].score.nll);
    r.heldout_nll_error.push_back(difference_error(e, 1, trials[i].score, trials[c.best].score));
  }
  c.size = sizes[c.best];
  c.smoothing = trials[c.best].smoothing;
  c.fits = trials[c.best].fits;
  c.score = std::move(trials[c.best].score);
  for (SizeTrial& trial : trials) c.half_fits.push_back(std::move(trial.fits));
  return c;
}

}  // namespace stf::fit::stages
