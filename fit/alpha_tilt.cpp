#include "alpha_tilt.h"

#include <cmath>

#include "evaluate.h"
#include "stf/tilt.h"

namespace stf::fit {

double tilt_from_counts(const std::vector<double>& edges, const std::vector<double>& counts) {
  double total = 0;
  for (double n : counts) total += n;
  if (!(total > 0)) return 0;
  auto log_likelihood = [&](double tilt) {
    double sum = 0;
    for (std::size_t k = 0; k < counts.size(); ++k)
      if (counts[k] > 0) sum += counts[k] * std::log(std::max(1e-300, tilt_mass(tilt, edges[k], edges[k + 1])));
    return sum;
  };
  // The log-likelihood is concave in the tilt (e^{tilt u} is log-linear in (tilt, u), so its
  // integral over an interval is log-concave): a golden-section search finds the maximum.
  constexpr double kRatio = 0.6180339887498949;
  double lo = -kMaxTilt, hi = kMaxTilt;
  double a = hi - kRatio * (hi - lo), b = lo + kRatio * (hi - lo);
  double fa = log_likelihood(a), fb = log_likelihood(b);
  while (hi - lo > 1e-6) {
    if (fa < fb) {
      lo = a, a = b, fa = fb;
      b = lo + kRatio * (hi - lo), fb = log_likelihood(b);
    } else {
      hi = b, b = a, fb = fa;
      a = hi - kRatio * (hi - lo), fa = log_likelihood(a);
    }
  }
  return 0.5 * (lo + hi);
}

std::vector<double> fit_alpha_tilts(const Table& t) {
  std::vector<double> tilts;
  if (t.sub_bins == 0) return tilts;
  const std::size_t subs = std::size_t(t.sub_bins);
  for (int b = 0; b < t.alpha_bins; ++b) {
    std::vector<double> edges(subs + 1), counts(subs);
    for (std::size_t k = 0; k <= subs; ++k) edges[k] = t.sub_edge(b, int(k));
    for (std::size_t k = 0; k < subs; ++k)
      counts[k] = t.multiple_sub_half[0][std::size_t(b) * subs + k] + t.multiple_sub_half[1][std::size_t(b) * subs + k];
    tilts.push_back(tilt_from_counts(edges, counts));
  }
  return tilts;
}

void group_sub_bins(const Table& t, int f, Table& coarse) {
  coarse.sub_edges.clear();
  for (auto& h : coarse.multiple_sub_half) h.clear();
  coarse.sub_bins = t.sub_bins * f;
  if (t.sub_bins == 0) return;
  const std::size_t subs = std::size_t(t.sub_bins);
  for (int j = 0; j < t.alpha_bins / f; ++j) {
    double below = 0;  // area fraction of the group below fine bin a
    for (int a = j * f; a < (j + 1) * f; ++a) {
      const double share = area_share(t, a, f);
      for (std::size_t k = 0; k < subs; ++k) {
        coarse.sub_edges.push_back(below + share * t.sub_edge(a, int(k)));
        for (int h = 0; h < 2; ++h) coarse.multiple_sub_half[h].push_back(t.multiple_sub_half[h][std::size_t(a) * subs + k]);
      }
      below += share;
    }
    coarse.sub_edges.push_back(1.0);
  }
}

}  // namespace stf::fit
