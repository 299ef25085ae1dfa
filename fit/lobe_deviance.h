// The Ceres cost functions of a vMF fit: thin adapters from lobe parameters to the cell
// integrals of cell_integral.h, and from those to the Poisson deviance's residuals and their
// hand-written Jacobians (checked against finite differences in tests/fit/lobe_deviance_test.cpp).
#pragma once

#include <ceres/ceres.h>

#include <memory>
#include <vector>

#include "stf/fit/cell_integral.h"

namespace stf::fit {

inline constexpr double kMaxLogit = 40;  // lobe weights below e^-40 of the heaviest are zero to a double

// Lobe weights from logits as the deviance uses them: clamped to [-kMaxLogit, kMaxLogit], then
// the softmax.
std::vector<double> lobe_weights(std::vector<double> logits);

// Residuals: one per cell with counts, and one for all empty cells together (their deviance
// is 2 sum mu = 2 N (1 - sum of the other cells' probabilities)). Parameter blocks: softmax
// logits [K], log kappa [K], then the K mean directions [3] each (on SphereManifold<3>).
// Each lobe is integrated over the cells at the coarsest quadrature level accurate for its
// own kappa (QuadratureLevels::level_for_kappa): broad lobes at the cell centres, narrow ones
// on sub-cells, so a mixture costs what its narrowest lobe needs only once.
//
// Log kappa and the logits are used clamped to [min_kappa, max_kappa] and [-kMaxLogit,
// kMaxLogit], with no derivative beyond them: a parameter that runs past a bound stays there
// without holding the others back. (Bounds declared to Ceres would add a projected line
// search, with two or three more Jacobians, to every iteration.)
class PoissonDeviance final : public ceres::CostFunction {
 public:
  // The deviance of `lobes` lobes over the cells `cells` integrates (its counts, outward factors
  // and turn).
  PoissonDeviance(LobeIntegrator cells, int lobes, double min_kappa, double max_kappa);
  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override;

 private:
  struct Lobes;
  Lobes integrate(double const* const* params, bool derivatives) const;
  void jacobian(const Lobes& lobes, const std::vector<double>& p, const std::vector<double>& dr, double p_rest,
                double** jacobians) const;

  LobeIntegrator cells_;
  int lobes_;
  double min_log_kappa_, max_log_kappa_;
};

// A pooled neighbour's deviance (PooledBin): PoissonDeviance of its counts with every lobe's
// mean turned by R = R_y(angle), residuals scaled by sqrt(weight) so that its deviance counts
// weight times. R is orthogonal, so d r / d mean = (d r / d (R mean)) R.
//
// With slopes (a sloped pool, VmfFitOptions::sloped) the neighbour d = PooledBin::offset bins
// away sees each lobe's logit and log kappa moved by d times that lobe's slope, and its mean
// turned by d times a turn of its own on top of `angle`: the bin's lobes continued linearly in
// alpha. Three more parameter blocks then follow the means (slopes of the logits, of the log
// kappas, and the turns), shared by all the bin's neighbours; the bin's own deviance does not
// depend on them, so they take up the neighbours' change of shape instead of biasing the bin.
class TurnedDeviance final : public ceres::CostFunction {
 public:
  TurnedDeviance(std::unique_ptr<PoissonDeviance> inner, int lobes, double angle, double weight, bool sloped = false,
                 double offset = 0);
  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override;

 private:
  std::unique_ptr<PoissonDeviance> inner_;
  int lobes_;
  double angle_, scale_;
  bool sloped_;
  double offset_;
};

}  // namespace stf::fit
