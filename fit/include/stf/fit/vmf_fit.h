// Fits a mixture of von Mises-Fisher lobes to one alpha bin's direction histogram by the
// binned Poisson likelihood (Ceres, Levenberg-Marquardt on deviance residuals).
#pragma once

#include <vector>

#include "stf/fit/cell_integral.h"
#include "stf/core/grid.h"
#include "stf/vmf.h"

namespace stf::fit {

// A neighbouring alpha bin's escapes fitted together with a bin's own: they are expected to
// follow the bin's lobes turned by `angle` about y (the axis the exit point turns about as
// alpha grows), times the neighbour's own outward factor, and their log-likelihood counts
// `weight` times.
struct PooledBin {
  const std::vector<double>* counts = nullptr;
  const OutwardFactors* outward = nullptr;  // null: plain lobes
  double angle = 0, weight = 0;
  int offset = 0;  // its bin minus the fitted one: how far sloped lobes are continued
  const BinTurn* turn = nullptr;  // how the neighbour's own density turns across it, or null
};

struct VmfFitOptions {
  const OutwardFactors* outward = nullptr;  // hemispherical lobes of this bin, or null
  const BinTurn* turn = nullptr;            // the bin's density turns across it, or null
  std::vector<PooledBin> pooled;            // neighbours fitted jointly (none: the bin alone)
  // Whether the neighbours see the lobes continued linearly in alpha (each lobe's logit, log
  // kappa and turn sloped by parameters of their own, fitted with the lobes) rather than as
  // they are: a local-linear fit, whose neighbours tell the bin's lobes nothing of their change
  // of shape, only of what the bin shares with them.
  bool sloped = false;
  int max_iterations = 100;
  // Stop once the deviance changes by less than this share of itself between iterations:
  // 1e-5 is ~0.05 at the deviances of a bin's few thousand cells, far below one unit, the
  // scale of statistically meaningful differences. (Larger steps toward it are no guide: a fit
  // from split lobes can move by less than 1e-4 per iteration with thousands of units to go.)
  double function_tolerance = 1e-5;
  // Bounds on kappa (the weights' logits are bounded to [-40, 40]). A parameter at its bound
  // stays there while the others converge (PoissonDeviance).
  double min_kappa = 1e-6, max_kappa = 1e8;
};

struct VmfFitResult {
  std::vector<VmfLobe> lobes;  // weights sum to 1
  double deviance = 0;         // Poisson deviance of the fit: 2 sum n log(n / mu) - (n - mu), pooled bins weighted in
  int iterations = 0;
};

// `counts` per cell of the grid; their total must be > 0. Each lobe is integrated at the
// quadrature level its kappa needs (QuadratureLevels::level_for_kappa).
VmfFitResult fit_vmf(const std::vector<double>& counts, const QuadratureLevels& levels, int lobes,
                     const VmfFitOptions& options = {});

// K start lobes from a fit with fewer (or as many): its heaviest lobes split in two.
std::vector<VmfLobe> grow_lobes(std::vector<VmfLobe> lobes, int K);

// The same, from given start lobes (e.g. a fit of the same size to fewer escapes).
VmfFitResult fit_vmf_from(const std::vector<double>& counts, const QuadratureLevels& levels,
                          const std::vector<VmfLobe>& start, const VmfFitOptions& options = {});

}  // namespace stf::fit
