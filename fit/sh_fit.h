// Spherical-harmonic smoothing of one alpha bin's direction histogram.
#pragma once

#include <memory>
#include <vector>

#include "stf/core/grid.h"
#include "stf/model.h"

namespace stf::fit {

// Projects cell histograms onto real SH up to band limit L: HEALPix grids through
// healpix_cxx's map2alm_iter (equal-area cells, iterative quadrature); other grids by least
// squares against the basis averaged over each cell (exact cell solid angles), with the
// normal matrix factorised once per grid.
class ShProjector {
 public:
  ShProjector(const DirectionGrid& grid, int band_limit);
  ~ShProjector();
  // Coefficients of the density per steradian f_c = counts_c / (total * solid_angle_c).
  std::vector<double> project(const std::vector<double>& counts) const;

 private:
  int band_limit_;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// How a projection is smoothed: optionally Lanczos sigma factors against ringing
// (sinc(l / (L + 1))), times heat-kernel smoothing exp(-t l (l + 1)). The fitter picks both on
// held-out data; neither at all (a plain projection) is among the choices.
struct ShSmoothing {
  bool lanczos = false;
  double t = 0;
};
// Applies `smoothing` in place. The l = 0 term, the total mass, is untouched.
void smooth_sh(std::vector<double>& coefficients, int band_limit, const ShSmoothing& smoothing);

// Cell probabilities of max(SH density, 0), renormalised, given the basis evaluated at the
// quadrature points ([points * count], row-major).
std::vector<double> clamped_sh_cell_probabilities(const std::vector<double>& coefficients,
                                                  const std::vector<double>& basis_at_points,
                                                  const CellQuadrature& q);

// Real SH basis at every quadrature point.
std::vector<double> sh_basis_at(const CellQuadrature& q, int band_limit);

// Fits every SH coefficient across the fitted bins as a Chebyshev series of degree
// model.alpha_degree in cos(alpha) at the bin centres, least squares weighted by each bin's
// escapes, and replaces the bins' coefficients by its values.
void compress_across_alpha(StfModel& model, const std::vector<double>& escapes);

}  // namespace stf::fit
