// A table's escapes as the fit sees them, and the probabilities of its parts (fit_stages.h).
#include <numeric>

#include "fit_stages.h"

namespace stf::fit::stages {

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

void Escapes::set_lifted() {
  for (int b = 0; b < table.alpha_bins; ++b)
    still.push_back({0, table.alpha_edges[std::size_t(b)], table.alpha_edges[std::size_t(b) + 1], 0, true});
}

double sum(const std::vector<double>& v) { return std::accumulate(v.begin(), v.end(), 0.0); }

double both_halves(const Table& t, int b) { return sum(bin_counts(t, 0, b)) + sum(bin_counts(t, 1, b)); }

double heading(const Table& t, const std::vector<double>& counts) {
  double x = 0, z = 0;
  for (std::int64_t c = 0; c < t.cells; ++c) x += counts[c] * t.direction[c][0], z += counts[c] * t.direction[c][2];
  return std::atan2(x, z);
}

double uncollided_escapes(const Table& t) {
  return t.uncollided_half[0] >= 0 ? t.uncollided_half[0] + t.uncollided_half[1] : 0.0;
}

bool singular_parts_exact(const Table& t) { return t.once_tallied && t.uncollided_half[0] >= 0; }

SingularParts medium_singular_parts(const Table& t) {
  const double tau = t.medium.tau();
  return {std::exp(-tau), t.max_scatter == 0 ? 0.0 : t.medium.albedo() * once_scattered_probability(tau, t.medium.g)};
}

SingularParts singular_parts(const Table& t) {
  if (!singular_parts_exact(t)) return {uncollided_escapes(t) / double(t.paths), 0.0};
  return medium_singular_parts(t);
}

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

bool worth_pooling(const Escapes& e, int b) { return e.total[std::size_t(b)] < kConfig.pool_below_escapes; }

bool capped_by_escapes(const Escapes& e, int b, int size) {
  return e.total[std::size_t(b)] < 2 * kConfig.escapes_per_lobe * size;
}

bool noisy(const Escapes& e, int b, int size) {
  return worth_pooling(e, b) && e.total[std::size_t(b)] < kConfig.sloped_pool_escapes_per_lobe * size;
}

std::vector<double> uniform_alpha(const std::vector<double>& edges) {
  std::vector<double> p(edges.size() - 1);
  for (std::size_t b = 0; b + 1 < edges.size(); ++b) p[b] = 0.5 * (std::cos(edges[b]) - std::cos(edges[b + 1]));
  return p;
}

}  // namespace stf::fit::stages
