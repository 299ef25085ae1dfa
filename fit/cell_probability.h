// Probabilities of a table's cells under a fitted direction density: the model integrated
// over each cell by the grid's cell quadrature (not its centre value times the solid angle,
// which fails where a lobe is narrow against a cell).
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "grid.h"
#include "stf/vmf.h"

namespace stf::fit {

// The sub-cell widening of a vMF lobe: a quadrature point stands for its whole sub-cell, so a
// lobe narrower than the sub-cell is spread by the sub-cell's own angular variance
// (solid angle / 12 per axis for a square): 1 / kappa_eff = 1 / kappa + solid_angle / 12.
// Each lobe's masses are then renormalised over the sphere, so a near-delta lobe still puts
// its whole weight into the cells around its mean.
// This is also the quadrature's second-order correction for broad lobes.
inline double widened_kappa(double kappa, double sub_cell_solid_angle) {
  return kappa / (1 + kappa * sub_cell_solid_angle / 12);
}

// Per-cell probabilities of a vMF mixture (weights summing to 1); they sum to 1.
// With `factor` (one value per quadrature point), each lobe is multiplied by it before its
// masses are normalised: hemispherical lobes.
std::vector<double> vmf_cell_probabilities(const std::vector<VmfLobe>& lobes, const CellQuadrature& q,
                                           const std::vector<double>* factor = nullptr);

// Per-cell probabilities of a density per steradian, normalised to sum to 1 (all zero if the
// density vanishes everywhere).
std::vector<double> density_cell_probabilities(const std::function<double(const Vec3&)>& density,
                                               const CellQuadrature& q);

// Poisson deviance 2 sum [n log(n / mu) - (n - mu)] of counts against mu = total * p: twice
// the log-likelihood ratio of the saturated model; smaller is a better fit.
double poisson_deviance(const std::vector<double>& counts, const std::vector<double>& p);

}  // namespace stf::fit
