#include "stf/fit/alpha_tilt.h"

#include <cmath>

#include "stf/quadrature.h"
#include "stf/tilt.h"

namespace stf::fit {

double area_share(const Table& reference, int b, int f) {
  auto area = [&](int lo, int hi) { return std::cos(reference.alpha_edges[lo]) - std::cos(reference.alpha_edges[hi]); };
  const int j = b / f;
  return area(b, b + 1) / area(j * f, (j + 1) * f);
}

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

std::vector<double> fit_alpha_tilts(const Table& t, int half) {
  std::vector<double> counts;
  for (std::size_t j = 0; t.sub_bins > 0 && j < t.multiple_sub_half[0].size(); ++j)
    counts.push_back((half != 1 ? t.multiple_sub_half[0][j] : 0.0) + (half != 0 ? t.multiple_sub_half[1][j] : 0.0));
  return tilts_from_sub_counts(t, counts);
}

std::vector<double> tilts_from_sub_counts(const Table& t, const std::vector<double>& sub_counts) {
  std::vector<double> tilts;
  if (t.sub_bins == 0) return tilts;
  const std::size_t subs = std::size_t(t.sub_bins);
  for (int b = 0; b < t.alpha_bins; ++b) {
    std::vector<double> edges(subs + 1);
    for (std::size_t k = 0; k <= subs; ++k) edges[k] = t.sub_edge(b, int(k));
    const auto first = sub_counts.begin() + std::ptrdiff_t(std::size_t(b) * subs);
    tilts.push_back(tilt_from_counts(edges, std::vector<double>(first, first + std::ptrdiff_t(subs))));
  }
  return tilts;
}

std::vector<std::pair<int, double>> blend_shares(const StfModel& m, int b, double u0, double u1) {
  const double tilt = m.tilt(b);
  const int width = m.blend_width(b);
  if (width <= 0) return {{b, tilt_mass(tilt, u0, u1)}};
  std::vector<std::pair<int, double>> shares;
  for (int j = std::max(0, b - width); j <= std::min(m.bins() - 1, b + width); ++j) shares.emplace_back(j, 0.0);
  // The weights are linear in u but for their normalisation near the first and last bin, with
  // kinks only at the bin's middle: Gauss-Legendre on each side, 16 panels, resolves them and
  // e^{40 u}.
  int bins[2 * StfModel::kMaxBlend + 1];
  double weights[2 * StfModel::kMaxBlend + 1];
  constexpr int kPanels = 16;
  for (auto [a, z] : {std::pair{u0, std::min(u1, 0.5)}, std::pair{std::max(u0, 0.5), u1}}) {
    if (!(z > a)) continue;
    for (int p = 0; p < kPanels; ++p)
      for (std::size_t s = 0; s < shares.size(); ++s)
        shares[s].second += gauss8(
            [&](double u) {
              const int n = m.blend_weights(b, u, bins, weights);
              double w = 0;
              for (int k = 0; k < n; ++k) w += bins[k] == shares[s].first ? weights[k] : 0.0;
              return w * tilt_density(tilt, u);
            },
            a + (z - a) * p / kPanels, a + (z - a) * (p + 1) / kPanels);
  }
  return shares;
}

std::vector<double> blended_cells(const StfModel& m, int b, const CellsInBin& cells_in_b) {
  std::vector<double> p(cells_in_b(b).size(), 0.0);
  for (const auto& [j, share] : blend_shares(m, b, 0, 1)) {
    const std::vector<double>& cells = cells_in_b(j);
    for (std::size_t c = 0; c < p.size(); ++c) p[c] += share * cells[c];
  }
  return p;
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
