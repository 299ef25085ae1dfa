// The hand-written Jacobians of the vMF fit's cost functions against central differences:
// plain, hemispherical and turning bins, and pooled neighbours flat and sloped. The cost
// normalises each mean, so along a mean its Jacobian is compared in the tangent space of the
// unit sphere (the fit's manifold).
#include "lobe_deviance.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "stf/core/rng.h"

namespace stf::fit {
namespace {

double uniform(std::uint64_t& s) { return double(splitmix64(s) >> 11) * 0x1p-53; }

// Counts of 2000 escapes drawn from two lobes, binned on a coarse grid: a histogram with full
// and empty cells, as a bin's.
std::vector<double> histogram(const DirectionGrid& grid) {
  const VmfLobe lobes[2] = {{0.7, 8, normalize({0.3, 0.1, 1})}, {0.3, 3, normalize({-0.5, 0.2, 0.4})}};
  std::vector<double> counts(std::size_t(grid.cell_count()), 0.0);
  std::uint64_t s = 11;
  for (int i = 0; i < 2000; ++i) {
    const VmfLobe& l = lobes[uniform(s) < 0.7 ? 0 : 1];
    counts[std::size_t(grid.cell(sample_vmf(l, uniform(s), uniform(s))))] += 1;
  }
  return counts;
}

// Parameters away from every bound and quadrature-level switch: logits, log kappas (kappa 4
// and 12), then the means (not unit: the cost normalises them).
struct Point {
  std::vector<double> logits{0.2, -0.4}, log_kappa{std::log(4.0), std::log(12.0)};
  std::vector<double> mean0{0.2, -0.1, 0.9}, mean1{-0.6, 0.3, 0.5};
  std::vector<double> slopes_logit{0.05, -0.03}, slopes_kappa{0.02, 0.04}, turns{0.01, -0.02};
  std::vector<double*> blocks(bool sloped) {
    std::vector<double*> b{logits.data(), log_kappa.data(), mean0.data(), mean1.data()};
    if (sloped) b.insert(b.end(), {slopes_logit.data(), slopes_kappa.data(), turns.data()});
    return b;
  }
};

// The largest difference between `cost`'s Jacobian and central differences of its residuals,
// relative to max(1, |entry|). Steps of 1e-5: the differences err by about 1e-9 (they are
// second order in the step; much smaller steps meet the rounding of the vectorised exp); a
// dropped term or a wrong sign errs by order 1.
double jacobian_error(const ceres::CostFunction& cost, bool sloped) {
  Point point;
  std::vector<double*> blocks = point.blocks(sloped);
  for (int k = 0; k < 2; ++k) {  // unit means: their tangent space is the plane normal to them
    double* m = blocks[std::size_t(2 + k)];
    const double n = std::sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
    for (int i = 0; i < 3; ++i) m[i] /= n;
  }
  const int rows = cost.num_residuals();
  const std::vector<std::int32_t>& sizes = cost.parameter_block_sizes();
  std::vector<std::vector<double>> J(sizes.size());
  std::vector<double*> J_out;
  for (std::size_t i = 0; i < sizes.size(); ++i) J[i].resize(std::size_t(rows * sizes[i])), J_out.push_back(J[i].data());
  std::vector<double> r(static_cast<std::size_t>(rows)), plus(r.size()), minus(r.size());
  EXPECT_TRUE(cost.Evaluate(blocks.data(), r.data(), J_out.data()));
  constexpr double h = 1e-5;
  double worst = 0;
  for (std::size_t i = 0; i < sizes.size(); ++i) {
    const bool mean = i == 2 || i == 3;
    for (int col = 0; col < sizes[i]; ++col) {
      double& x = blocks[i][col];
      const double x0 = x;
      x = x0 + h, cost.Evaluate(blocks.data(), plus.data(), nullptr);
      x = x0 - h, cost.Evaluate(blocks.data(), minus.data(), nullptr);
      x = x0;
      for (int row = 0; row < rows; ++row) {
        double analytic = J[i][std::size_t(row * sizes[i] + col)];
        if (mean) {  // J (I - m m^T): the normalisation removes the radial part
          double radial = 0;
          for (int a = 0; a < 3; ++a) radial += J[i][std::size_t(row * 3 + a)] * blocks[i][a];
          analytic -= radial * blocks[i][col];
        }
        const double numeric = (plus[std::size_t(row)] - minus[std::size_t(row)]) / (2 * h);
        worst = std::max(worst, std::abs(analytic - numeric) / std::max(1.0, std::abs(numeric)));
      }
    }
  }
  return worst;
}

class LobeDeviance : public ::testing::Test {
 protected:
  std::unique_ptr<DirectionGrid> grid = make_grid("healpix:4");
  QuadratureLevels levels{*grid};
  std::vector<double> counts = histogram(*grid);
  OutwardFactors outward = outward_factors(levels, 0.3, 0.6);
  BinTurn turn{4, 0.3, 0.6, 0.2};  // 3 and 5 turned copies of the two lobes
};

TEST_F(LobeDeviance, PlainLobesMatchFiniteDifferences) {
  EXPECT_LT(jacobian_error(PoissonDeviance(LobeIntegrator(levels, counts, nullptr, nullptr), 2, 1e-6, 1e8), false), 1e-6);
}

TEST_F(LobeDeviance, HemisphericalLobesMatchFiniteDifferences) {
  EXPECT_LT(jacobian_error(PoissonDeviance(LobeIntegrator(levels, counts, &outward, nullptr), 2, 1e-6, 1e8), false), 1e-6);
}

TEST_F(LobeDeviance, TurningBinMatchesFiniteDifferences) {
  EXPECT_LT(jacobian_error(PoissonDeviance(LobeIntegrator(levels, counts, &outward, &turn), 2, 1e-6, 1e8), false), 1e-6);
}

TEST_F(LobeDeviance, LiftedLobesMatchFiniteDifferences) {
  for (const BinTurn& lifted : {BinTurn{0, 0.3, 0.6, 0.2, true}, BinTurn{4, 0.3, 0.6, 0.2, true}}) {
    EXPECT_LT(jacobian_error(PoissonDeviance(LobeIntegrator(levels, counts, nullptr, &lifted), 2, 1e-6, 1e8), false), 1e-6)
        << "rate " << lifted.rate;
  }
}

TEST_F(LobeDeviance, PooledNeighbourMatchesFiniteDifferences) {
  auto inner = std::make_unique<PoissonDeviance>(LobeIntegrator(levels, counts, &outward, &turn), 2, 1e-6, 1e8);
  EXPECT_LT(jacobian_error(TurnedDeviance(std::move(inner), 2, 0.1, 0.5), false), 1e-6);
}

TEST_F(LobeDeviance, SlopedPoolMatchesFiniteDifferences) {
  auto inner = std::make_unique<PoissonDeviance>(LobeIntegrator(levels, counts, &outward, &turn), 2, 1e-6, 1e8);
  EXPECT_LT(jacobian_error(TurnedDeviance(std::move(inner), 2, 0.1, 0.5, true, -2), true), 1e-6);
}

// The check can fail: a Jacobian off by a sign in one block is caught.
TEST_F(LobeDeviance, AWrongJacobianIsCaught) {
  class Flipped final : public ceres::CostFunction {
   public:
    explicit Flipped(const ceres::CostFunction& inner) : inner_(inner) {
      set_num_residuals(inner.num_residuals());
      *mutable_parameter_block_sizes() = inner.parameter_block_sizes();
    }
    bool Evaluate(double const* const* p, double* r, double** j) const override {
      if (!inner_.Evaluate(p, r, j)) return false;
      if (j && j[1])
        for (int i = 0; i < 2 * num_residuals(); ++i) j[1][i] = -j[1][i];
      return true;
    }

   private:
    const ceres::CostFunction& inner_;
  };
  const PoissonDeviance deviance(LobeIntegrator(levels, counts, nullptr, nullptr), 2, 1e-6, 1e8);
  EXPECT_GT(jacobian_error(Flipped(deviance), false), 1e-2);
}

}  // namespace
}  // namespace stf::fit
