#include "stf/fit/vmf_fit.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "lobe_deviance.h"

namespace stf::fit {

namespace {

// Spherical k-means and EM start lobes no narrower than this; the likelihood stage may narrow
// them further, up to VmfFitOptions::max_kappa (1e8). A lobe already inside one cell barely
// changes the binned likelihood as it narrows, so near-delta lobes tend to end near 1e7.
constexpr double kMaxStartKappa = 1e7;

// Banerjee et al. (2005): kappa from the mean resultant length R in 3D.
double kappa_from_resultant(double r) {
  r = std::clamp(r, 0.0, 1 - 1e-12);
  return r * (3 - r * r) / (1 - r * r);
}

// EM for a vMF mixture on cell centres weighted by counts (Banerjee et al. 2005): soft
// assignments refine the k-means start, so Levenberg-Marquardt starts near the optimum.
void em_on_cells(const std::vector<double>& counts, const std::vector<Vec3>& centre,
                 std::vector<VmfLobe>& lobes, int iterations, double max_kappa) {
  const int K = int(lobes.size());
  std::vector<double> r(K);
  for (int it = 0; it < iterations; ++it) {
    std::vector<Vec3> sum(K, Vec3{0, 0, 0});
    std::vector<double> mass(K, 0);
    for (std::size_t c = 0; c < counts.size(); ++c) {
      if (counts[c] <= 0) continue;
      double norm = 0;
      for (int k = 0; k < K; ++k) norm += r[k] = lobes[k].weight * vmf_pdf(lobes[k].kappa, dot(lobes[k].mean, centre[c]));
      if (norm <= 0) continue;
      for (int k = 0; k < K; ++k) {
        double w = counts[c] * r[k] / norm;
        mass[k] += w;
        sum[k] += w * centre[c];
      }
    }
    double total = 0;
    for (double m : mass) total += m;
    for (int k = 0; k < K; ++k) {
      double len = length(sum[k]);
      if (mass[k] <= 1e-9 * total || len <= 0) continue;  // a starved lobe keeps its place
      lobes[k] = {mass[k] / total, std::min(kappa_from_resultant(len / mass[k]), max_kappa),
                  {sum[k].x / len, sum[k].y / len, sum[k].z / len}};
    }
  }
}

// The deterministic starting point: spherical k-means on the cell centres
// (QuadratureLevels::centres) weighted by counts (seeded at the fullest cell, then
// farthest-first), weights from the cluster masses, kappa from each cluster's mean resultant
// length (Banerjee et al. 2005).
std::vector<VmfLobe> initial_lobes(const std::vector<double>& counts, const std::vector<Vec3>& centre, int K) {
  const std::size_t cells = counts.size();
  // Counts at cell centres resolve no lobe narrower than a cell: a cluster of one cell has a
  // resultant of 1 and would start as a point lobe (kappa at the cap) that the binned
  // likelihood can no longer move or widen, holding that cell's count while the other lobes
  // fit the rest around it. Start lobes are at most as narrow as one mean cell (2 pi / kappa
  // = 4 pi / cells); the likelihood stage narrows them where the data ask for it.
  const double resolved = std::min(kMaxStartKappa, 0.5 * double(cells));
  std::vector<Vec3> mean;
  mean.push_back(centre[std::max_element(counts.begin(), counts.end()) - counts.begin()]);
  while (int(mean.size()) < K) {
    double best = -1;
    std::size_t pick = 0;
    for (std::size_t c = 0; c < cells; ++c) {
      double nearest = -1;
      for (const Vec3& m : mean) nearest = std::max(nearest, dot(m, centre[c]));
      double score = counts[c] * (1 - nearest);
      if (score > best) best = score, pick = c;
    }
    mean.push_back(centre[pick]);
  }
  std::vector<VmfLobe> lobes(K);
  for (int iteration = 0; iteration < 20; ++iteration) {
    std::vector<Vec3> sum(K, Vec3{0, 0, 0});
    std::vector<double> mass(K, 0);
    for (std::size_t c = 0; c < cells; ++c) {
      int best = 0;
      for (int k = 1; k < K; ++k)
        if (dot(mean[k], centre[c]) > dot(mean[best], centre[c])) best = k;
      Vec3& s = sum[best];
      s += counts[c] * centre[c];
      mass[best] += counts[c];
    }
    double total = 0;
    for (double m : mass) total += m;
    for (int k = 0; k < K; ++k) {
      double len = length(sum[k]);
      if (mass[k] <= 0 || len <= 0) {  // an empty cluster: a faint uniform lobe
        lobes[k] = {1e-3, 1e-3, mean[k]};
        continue;
      }
      mean[k] = {sum[k].x / len, sum[k].y / len, sum[k].z / len};
      lobes[k] = {mass[k] / total, std::min(kappa_from_resultant(len / mass[k]), resolved), mean[k]};
    }
  }
  double total = 0;
  for (const VmfLobe& l : lobes) total += l.weight;
  for (VmfLobe& l : lobes) l.weight /= total;
  em_on_cells(counts, centre, lobes, 30, resolved);
  return lobes;
}

ceres::Solver::Options solver_options(const VmfFitOptions& options) {
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  solver.max_num_iterations = options.max_iterations;
  solver.function_tolerance = options.function_tolerance;
  solver.num_threads = 1;
  solver.logging_type = ceres::SILENT;
  return solver;
}

// The lobes of the solved parameters, as the deviance saw them: clamped to their bounds.
std::vector<VmfLobe> solved_lobes(const std::vector<double>& logits, const std::vector<double>& log_kappa,
                                  const std::vector<double>& means, const VmfFitOptions& options) {
  const std::vector<double> weight = lobe_weights(logits);
  std::vector<VmfLobe> lobes;
  for (std::size_t k = 0; k < logits.size(); ++k)
    lobes.push_back({weight[k],
                     std::exp(std::clamp(log_kappa[k], std::log(options.min_kappa), std::log(options.max_kappa))),
                     normalize({means[3 * k], means[3 * k + 1], means[3 * k + 2]})});
  return lobes;
}

}  // namespace

VmfFitResult fit_vmf_from(const std::vector<double>& counts, const QuadratureLevels& levels,
                          const std::vector<VmfLobe>& start, const VmfFitOptions& options) {
  const int K = int(start.size());
  std::vector<double> logits(K), log_kappa(K), means(3 * K);
  for (int k = 0; k < K; ++k) {
    logits[k] = std::log(std::max(start[k].weight, 1e-12));
    log_kappa[k] = std::log(std::clamp(start[k].kappa, options.min_kappa * 10, std::min(kMaxStartKappa, options.max_kappa / 10)));
    means[3 * k] = start[k].mean.x, means[3 * k + 1] = start[k].mean.y, means[3 * k + 2] = start[k].mean.z;
  }
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  std::vector<double*> blocks = {logits.data(), log_kappa.data()};
  for (int k = 0; k < K; ++k) blocks.push_back(&means[3 * k]);
  problem.AddResidualBlock(
      new PoissonDeviance(LobeIntegrator(levels, counts, options.outward, options.turn), K, options.min_kappa,
                          options.max_kappa),
      nullptr, blocks);
  // Slopes of the logits, the log kappas and the turns (sloped pools), from none.
  std::vector<double> slopes(options.sloped && !options.pooled.empty() ? 3 * std::size_t(K) : 0, 0.0);
  std::vector<double*> pooled_blocks = blocks;
  for (std::size_t i = 0; i < slopes.size(); i += std::size_t(K)) pooled_blocks.push_back(&slopes[i]);
  for (const PooledBin& n : options.pooled)
    problem.AddResidualBlock(
        new TurnedDeviance(std::make_unique<PoissonDeviance>(LobeIntegrator(levels, *n.counts, n.outward, n.turn), K,
                                                             options.min_kappa, options.max_kappa),
                           K, n.angle, n.weight, !slopes.empty(), n.offset),
        nullptr, pooled_blocks);
  ceres::SphereManifold<3> sphere;
  for (int k = 0; k < K; ++k) problem.SetManifold(&means[3 * k], &sphere);
  // The weights are a softmax of the logits, unchanged when all move together: the first is
  // held, so that J^T J has no null direction and the normal equations (a quarter of the work
  // of a QR of the cells-by-parameters Jacobian) can be solved by Cholesky.
  std::unique_ptr<ceres::SubsetManifold> first_logit_held;
  if (K == 1) {
    problem.SetParameterBlockConstant(logits.data());
    if (!slopes.empty()) problem.SetParameterBlockConstant(slopes.data());
  } else {
    first_logit_held = std::make_unique<ceres::SubsetManifold>(K, std::vector<int>{0});
    problem.SetManifold(logits.data(), first_logit_held.get());
    if (!slopes.empty()) problem.SetManifold(slopes.data(), first_logit_held.get());
  }

  ceres::Solver::Summary summary;
  ceres::Solve(solver_options(options), &problem, &summary);
  VmfFitResult result;
  result.iterations = int(summary.iterations.size());
  result.deviance = 2 * summary.final_cost;
  result.lobes = solved_lobes(logits, log_kappa, means, options);
  return result;
}

std::vector<VmfLobe> grow_lobes(std::vector<VmfLobe> lobes, int K) {
  // Lobes of zero weight (a bin with fewer escapes than lobes) are dropped first.
  lobes.erase(std::remove_if(lobes.begin(), lobes.end(), [](const VmfLobe& l) { return l.weight <= 0; }), lobes.end());
  if (int(lobes.size()) > K) lobes.resize(std::size_t(K));
  if (lobes.empty() && K > 0) lobes.push_back({1, 1e-3, {0, 0, 1}});
  while (int(lobes.size()) < K) {
    // The heaviest lobe becomes two, half a standard deviation to each side of its mean, so
    // the likelihood's gradient can pull them apart.
    VmfLobe& l = *std::max_element(lobes.begin(), lobes.end(), [](const VmfLobe& a, const VmfLobe& b) { return a.weight < b.weight; });
    const Vec3 b1 = Frame::around(l.mean).x;
    const double offset = std::min(0.5, 0.5 / std::sqrt(std::max(l.kappa, 1e-6)));
    VmfLobe twin = l;
    l.weight *= 0.5, twin.weight = l.weight;
    l.mean = normalize(l.mean + offset * b1);
    twin.mean = normalize(twin.mean - offset * b1);
    lobes.push_back(twin);
  }
  double total = 0;
  for (const VmfLobe& l : lobes) total += l.weight;
  for (VmfLobe& l : lobes) l.weight /= total;
  return lobes;
}

VmfFitResult fit_vmf(const std::vector<double>& counts, const QuadratureLevels& levels, int K,
                     const VmfFitOptions& options) {
  const bool lifted = options.turn && options.turn->lifted;
  if (!options.outward && !lifted) return fit_vmf_from(counts, levels, initial_lobes(counts, levels.centres(), K), options);
  // Hemispherical and lifted lobes have more poor local optima than plain ones: K lobes grow from
  // a fit of half as many (the heaviest split), down to two from k-means.
  if (K > 2) return fit_vmf_from(counts, levels, grow_lobes(fit_vmf(counts, levels, (K + 1) / 2, options).lobes, K), options);
  if (lifted) {
    // Lifted lobes start where they put the counts: their means at the cells' centres mapped
    // about the bin's middle normal (LobeIntegrator::PointFactor::lift).
    const double middle = 0.5 * (options.turn->a0 + options.turn->a1);
    const Vec3 n{std::sin(middle), 0, std::cos(middle)};
    std::vector<Vec3> mapped;
    for (const Vec3& c : levels.centres()) mapped.push_back(2 * dot(c, n) * c - n);
    return fit_vmf_from(counts, levels, initial_lobes(counts, mapped, K), options);
  }
  // They are multiplied by the outward factor, so they start from the counts with that factor
  // divided out (floored, so that grazing cells do not dominate): the shape the lobes
  // themselves must take.
  std::vector<double> lobe_counts(counts);
  const std::vector<double>& factor = (*options.outward)[0];
  for (std::size_t c = 0; c < lobe_counts.size(); ++c) lobe_counts[c] = factor[c] > 0 ? counts[c] / std::max(factor[c], 0.1) : 0.0;
  return fit_vmf_from(counts, levels, initial_lobes(lobe_counts, levels.centres(), K), options);
}

}  // namespace stf::fit
