// The once-scattered part: its probability and alpha marginal against a quadrature written
// apart (mu space, the textbook exit distance), its exact binning against its sampler
// (chi-square), and the whole sampler with all three parts against the binned model.
#include "stf/once_scattered.h"

#include <gtest/gtest.h>

#include <cmath>

#include "chi2.h"
#include "stf/measure/evaluate.h"
#include "stf/core/grid.h"
#include "stf/core/rng.h"
#include "seed.h"
#include "stf/hg.h"
#include "stf/sampler.h"
#include "test_models.h"
#include "test_numerics.h"

namespace stf {
using namespace stf::measure;  // the measures of models (stf/measure/)
namespace {

using test::integrate;
using test::Uniforms;

// P(escape after one collision, exit angle in [a0, a1]) / albedo, in mu space: for fixed s the
// mu towards the exit point of angle a is (cos a - s) / sqrt(1 - 2 s cos a + s^2). The depth is
// s = 1 - (1 - x)^2, which takes the square root of sideways exits at s -> 1 out of the rule.
double once_in_alpha_band(double tau, double g, double a0, double a1) {
  auto towards = [](double a, double s) {
    const double c = std::cos(a);
    return (c - s) / std::sqrt(1 - 2 * s * c + s * s);
  };
  return integrate(
      [&](double x) {
        const double s = 1 - (1 - x) * (1 - x);
        return 2 * (1 - x) * tau * std::exp(-tau * s) *
               integrate(
                   [&](double mu) {
                     const double t = -s * mu + std::sqrt(1 - s * s * (1 - mu * mu));
                     return hg_pdf_mu(g, mu) * std::exp(-tau * t);
                   },
                   towards(a1, s), towards(a0, s), 1000);
      },
      0, 1, 64);
}

struct Medium {
  double tau, g;
};
const Medium kMedia[] = {{1, 0.3}, {0.05, -0.5}, {4.5, 0.9}, {30, 0}, {2, 0.99}, {1, -0.99}};

TEST(OnceScattered, ProbabilityAndAlphaMarginalMatchAQuadratureInMu) {
  std::unique_ptr<DirectionGrid> grid = make_grid("healpix:2");
  const int bins = 9;
  std::vector<double> edges;
  for (int b = 0; b <= bins; ++b) edges.push_back(kPi * b / bins);
  for (Medium m : kMedia) {
    if (std::abs(m.g) > 0.95) continue;  // HG is too narrow for the plain mu rule
    const double p = once_scattered_probability(m.tau, m.g);
    const double q = once_in_alpha_band(m.tau, m.g, 0, kPi);
    EXPECT_NEAR(p, q, 1e-6 * q) << "tau " << m.tau << " g " << m.g;
    fit::OnceScatteredCells cells = fit::bin_once_scattered(m.tau, m.g, edges, *grid);
    EXPECT_NEAR(cells.probability, p, 1e-6 * p);
    for (int b = 0; b < bins; ++b)
      EXPECT_NEAR(cells.bin_mass[b] * p, once_in_alpha_band(m.tau, m.g, edges[b], edges[b + 1]), 1e-6 * p)
          << "tau " << m.tau << " g " << m.g << " bin " << b;
  }
}

// Samples binned as the walk books escapes: alpha bin of the exit point, cell of the direction
// rotated so the point lies in the x-z plane, on the +y or -y side of y' = 0 by parity.
void bin_like_a_table(const Vec3& point, const Vec3& direction, int i, int bins, const DirectionGrid& grid,
                      std::vector<double>& counts, bool on_circle) {
  const double rho = std::hypot(point.x, point.y);
  const double cb = rho > 0 ? point.x / rho : 1, sb = rho > 0 ? point.y / rho : 0;
  Vec3 local{cb * direction.x + sb * direction.y, -sb * direction.x + cb * direction.y, direction.z};
  if (on_circle) local.y = i % 2 ? -1e-300 : 1e-300;
  const double alpha = std::acos(std::clamp(point.z, -1.0, 1.0));
  const int b = std::min(bins - 1, int(alpha / kPi * bins));
  counts[std::size_t(b) * grid.cell_count() + grid.cell(local)] += 1;
}

TEST(OnceScattered, SamplerMatchesTheExactBinningChiSquare) {
  const std::uint64_t seed = test::test_seed(81);
  SCOPED_TRACE(test::seed_trace(seed));
  std::unique_ptr<DirectionGrid> grid = make_grid("healpix:4");
  const int bins = 18, n = 300000;
  std::vector<double> edges;
  for (int b = 0; b <= bins; ++b) edges.push_back(kPi * b / bins);
  for (Medium m : kMedia) {
    const OnceScattered part(m.tau, m.g);
    EXPECT_GT(part.acceptance(), 0.3) << "tau " << m.tau << " g " << m.g;
    fit::OnceScatteredCells cells = fit::bin_once_scattered(m.tau, m.g, edges, *grid);
    std::vector<double> expected(std::size_t(bins) * grid->cell_count(), 0.0), observed(expected.size(), 0.0);
    for (int b = 0; b < bins; ++b)
      for (const auto& [c, share] : cells.cells[b]) expected[std::size_t(b) * grid->cell_count() + c] += n * share;
    Uniforms u{seed};
    for (int i = 0; i < n; ++i) {
      Vec3 point, direction;
      part.sample(u(), u(), u(), u(), point, direction);
      ASSERT_NEAR(length(point), 1, 1e-12);
      ASSERT_NEAR(length(direction), 1, 1e-12);
      ASSERT_GE(dot(point, direction), -1e-12) << "exits inwards";
      bin_like_a_table(point, direction, i, bins, *grid, observed, true);
    }
    test::Chi2Result r = test::chi2_test(observed, expected);
    EXPECT_GT(r.p_value, test::kChi2Alpha) << "tau " << m.tau << " g " << m.g << ": " << r.describe();
  }
}

// All three parts through ShellSampler: the smooth part (vMF), the uncollided delta and the
// once-scattered part, against the model binned like a table, at the model's alpha bins and at
// 3x finer ones (as a tolerance fit's model is evaluated: the smooth part spread by its tilted
// density in area and blended with its neighbours, the delta in the first fine bin alone).
void expect_sampler_matches_binned_model(const StfModel& model, std::uint64_t seed) {
  ASSERT_EQ(model_error(model), "");
  ShellSampler s(model);
  for (int f : {1, 3}) {
    Table layout;
    layout.grid = "healpix:2";
    std::unique_ptr<DirectionGrid> grid = make_grid(layout.grid);
    layout.cells = grid->cell_count();
    layout.alpha_bins = f * model.bins();
    for (int b = 0; b <= layout.alpha_bins; ++b) layout.alpha_edges.push_back(kPi * b / layout.alpha_bins);
    const measure::BinnedModel binned(model, layout, *grid);
    const fit::QuadratureLevels levels(*grid);
    const int n = 400000, bins = layout.alpha_bins;
    std::vector<double> expected, observed(std::size_t(bins) * layout.cells, 0.0);
    measure::SmoothCellCache smooth(model, levels);
    for (int b = 0; b < bins; ++b) {
      auto [probability, p] = binned.bin(b, std::ref(smooth));
      for (double v : p) expected.push_back(n * probability * v);
    }
    Uniforms u{seed + std::uint64_t(f)};
    int counts[3] = {0, 0, 0};
    for (int i = 0; i < n; ++i) {
      ExitSample x = s.sample(u(), u(), u(), u());
      ++counts[x.component];
      if (x.component == kOnceScattered) {
        ASSERT_EQ(x.pdf, model.once_fraction);
      } else if (x.component == kUncollided) {
        ASSERT_EQ(x.pdf, model.uncollided_probability());
      }
      bin_like_a_table(x.point, x.direction, i, bins, *grid, observed, x.component == kOnceScattered);
    }
    test::Chi2Result r = test::chi2_test(observed, expected);
    EXPECT_GT(r.p_value, test::kChi2Alpha) << "alpha bins " << f << "x the model's: " << r.describe();
    EXPECT_NEAR(counts[kOnceScattered], n * 0.3, 5 * std::sqrt(n * 0.3 * 0.7));
  }
}

StfModel every_part_model() {
  StfModel model = test::make_vmf_model();
  model.tau = 1.3, model.g = 0.4;
  model.uncollided_fraction = 0.4 * model.alpha_probability[0];
  model.once_fraction = 0.3;
  model.alpha_tilt = {-2.5, 1.0, 0.3, 0.0, -0.7, 4.0};  // spread over 3x finer bins as the sampler spreads them
  model.alpha_blend = 2;                                // with the directions of the neighbours blended in
  return model;
}

TEST(OnceScattered, FullSamplerWithEveryPartMatchesTheBinnedModelChiSquare) {
  const std::uint64_t seed = test::test_seed(82);
  SCOPED_TRACE(test::seed_trace(seed));
  expect_sampler_matches_binned_model(every_part_model(), seed);
}

// The same with hemispherical lobes that turn with the exit angle (StfModel::alpha_turn), by up to
// 90 degrees across a bin: the sampler turns each draw, the binned model turns the lobes' means
// and the bins' tangent planes slice by slice of exit angle, and at 3x finer alpha bins the
// turn decides which cells each third of a bin fills.
TEST(OnceScattered, TurningDensitiesMatchTheBinnedModelChiSquare) {
  const std::uint64_t seed = test::test_seed(83);
  SCOPED_TRACE(test::seed_trace(seed));
  StfModel model = every_part_model();
  model.hemispherical = true;
  model.rebuild_lobe_norms();
  model.alpha_turn = {1.5, -2.0, 3.0, 0.7, 1.0, -0.5};
  expect_sampler_matches_binned_model(model, seed);
}

}  // namespace
}  // namespace stf
