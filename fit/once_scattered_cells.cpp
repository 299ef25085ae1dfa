#include "stf/fit/once_scattered_cells.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "stf/once_scattered.h"
#include "stf/quadrature.h"

namespace stf::fit {

namespace {

// Runs of one cell along the circle (sin theta, side, cos theta): cell_of[k] holds mu in
// [edge[k], edge[k + 1]), edges increasing from -1 to 1. A scan fine against the grid's cells,
// each change of cell placed by bisection.
struct CirclePieces {
  std::vector<double> edge;
  std::vector<std::int64_t> cell_of;
};

CirclePieces circle_pieces(const DirectionGrid& grid, double side) {
  const int n = int(std::clamp(64 * std::sqrt(double(grid.cell_count())), 8192.0, double(1 << 20)));
  auto direction = [&](double theta) { return Vec3{std::sin(theta), side, std::cos(theta)}; };
  std::vector<double> x(std::size_t(n) + 1), y(x.size(), side), z(x.size());
  std::vector<std::int64_t> cell(x.size());
  // From theta = pi (mu = -1) to 0 (mu = 1), so the runs come out in increasing mu.
  for (int k = 0; k <= n; ++k) {
    const double theta = kPi * (n - k) / n;
    x[std::size_t(k)] = std::sin(theta), z[std::size_t(k)] = std::cos(theta);
  }
  grid.cells(x.data(), y.data(), z.data(), cell.data(), n + 1);
  CirclePieces p;
  p.edge.push_back(-1);
  p.cell_of.push_back(cell[0]);
  for (int k = 0; k < n; ++k) {
    if (cell[std::size_t(k) + 1] == cell[std::size_t(k)]) continue;
    double lo = kPi * (n - k) / n, hi = kPi * (n - k - 1) / n;  // theta of cell[k], of cell[k + 1]
    for (int it = 0; it < 60; ++it) {
      const double mid = 0.5 * (lo + hi);
      (grid.cell(direction(mid)) == cell[std::size_t(k)] ? lo : hi) = mid;
    }
    p.edge.push_back(std::cos(hi));
    p.cell_of.push_back(cell[std::size_t(k) + 1]);
  }
  p.edge.push_back(1);
  return p;
}

// HG's cumulative distribution of mu, without cancellation at g -> 0 or |g| -> 1:
// F = (1 - g)(1 + mu) / (D (1 + g + D)), D^2 = (1 - g)^2 + 2 g (1 - mu).
double hg_cdf(double g, double mu) {
  const double d = std::sqrt(std::max(0.0, (1 - g) * (1 - g) + 2 * g * (1 - mu)));
  return d > 0 ? std::clamp((1 - g) * (1 + mu) / (d * (1 + g + d)), 0.0, 1.0) : 1.0;
}

// The mu at which a path from (0, 0, s) reaches the exit point of angle alpha (cos a = c).
double mu_towards(double c, double s) { return (c - s) / std::sqrt(std::max(1e-300, 1 - 2 * s * c + s * s)); }

}  // namespace

OnceScatteredCells bin_once_scattered(double tau, double g, const std::vector<double>& alpha_edges,
                                      const DirectionGrid& grid) {
  const int bins = int(alpha_edges.size()) - 1;
  const HgParams<double> hg = HgParams<double>::make(g);
  auto mu_of = [&](double u) { return sample_hg(hg, u).cos_theta; };  // HG's quantile
  const CirclePieces sides[2] = {circle_pieces(grid, 1e-300), circle_pieces(grid, -1e-300)};
  std::vector<double> cos_edges;  // increasing: bin bins - 1 first
  for (int b = bins; b >= 0; --b) cos_edges.push_back(std::cos(alpha_edges[std::size_t(b)]));
  std::vector<double> u_lines;  // where the integrand's scale is set: the sampler's u grid
  for (double u : OnceScattered::u_edges()) u_lines.push_back(mu_of(u));

  std::vector<std::map<std::int64_t, double>> mass(std::size_t(std::max(bins, 0)));
  std::vector<double> cuts;
  auto add_depth = [&](double s, double weight) {
    for (const CirclePieces& side : sides) {
      cuts.assign(side.edge.begin(), side.edge.end());
      for (double c : cos_edges) cuts.push_back(std::clamp(mu_towards(c, s), -1.0, 1.0));
      cuts.insert(cuts.end(), u_lines.begin(), u_lines.end());
      std::sort(cuts.begin(), cuts.end());
      for (std::size_t k = 0; k + 1 < cuts.size(); ++k) {
        const double lo = cuts[k], hi = cuts[k + 1];
        if (!(hi > lo)) continue;
        const double mid = 0.5 * (lo + hi);
        const double ca = exit_cos_alpha(s, mid);
        const int from_top = int(std::upper_bound(cos_edges.begin(), cos_edges.end(), ca) - cos_edges.begin()) - 1;
        const int bin = std::clamp(bins - 1 - from_top, 0, bins - 1);
        const std::size_t run = std::size_t(std::upper_bound(side.edge.begin(), side.edge.end(), mid) - side.edge.begin()) - 1;
        const double in_piece = gauss8(
            [&](double u) { return std::exp(-tau * (s + exit_distance_from_axis(s, mu_of(u)) - 1)); },
            hg_cdf(g, lo), hg_cdf(g, hi));
        mass[std::size_t(bin)][side.cell_of[std::min(run, side.cell_of.size() - 1)]] += 0.5 * weight * in_piece;
      }
    }
  };
  const std::vector<double> s_edges = OnceScattered::s_edges();
  for (std::size_t i = 0; i + 1 < s_edges.size(); ++i) {
    const double mid = 0.5 * (s_edges[i] + s_edges[i + 1]), half = 0.5 * (s_edges[i + 1] - s_edges[i]);
    for (int k = 0; k < 4; ++k)
      for (double sign : {-1.0, 1.0}) add_depth(mid + sign * half * kGauss8Node[k], half * kGauss8Weight[k] * tau);
  }

  OnceScatteredCells r;
  double total = 0;
  for (const auto& bin : mass)
    for (const auto& [cell, m] : bin) total += m;
  r.probability = total * std::exp(-tau);  // the weights were taken relative to e^{-tau}
  r.bin_mass.assign(std::size_t(std::max(bins, 0)), 0.0);
  r.cells.resize(r.bin_mass.size());
  for (std::size_t b = 0; b < mass.size() && total > 0; ++b)
    for (const auto& [cell, m] : mass[b]) {
      r.cells[b].emplace_back(cell, m / total);
      r.bin_mass[b] += m / total;
    }
  return r;
}

}  // namespace stf::fit
