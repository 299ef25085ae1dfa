// Cell probabilities of vMF lobes by the plain point rule of a fine quadrature: each lobe's
// density at the points (widened by the sub-cell's own angular variance, solid angle / 12 per
// axis, so a lobe narrower than a sub-cell is not lost between points), its masses normalised
// over the sphere. The tests' reference for what stf/fit/cell_integral.h integrates faster.
#pragma once

#include <vector>

#include "stf/core/grid.h"
#include "stf/vmf.h"

namespace stf::test {

inline std::vector<double> reference_cells(const std::vector<VmfLobe>& lobes, const CellQuadrature& q) {
  const std::size_t cells = q.point.size() / std::size_t(q.per_cell);
  std::vector<double> p(cells, 0.0), mass(cells);
  for (const VmfLobe& lobe : lobes) {
    if (lobe.weight <= 0) continue;
    double total = 0;
    for (std::size_t c = 0; c < cells; ++c) {
      mass[c] = 0;
      for (int j = 0; j < q.per_cell; ++j) {
        const std::size_t k = c * std::size_t(q.per_cell) + std::size_t(j);
        const double kappa = lobe.kappa / (1 + lobe.kappa * q.weight[k] / 12);
        mass[c] += q.weight[k] * vmf_pdf(kappa, dot(lobe.mean, q.point[k]));
      }
      total += mass[c];
    }
    for (std::size_t c = 0; c < cells && total > 0; ++c) p[c] += lobe.weight * mass[c] / total;
  }
  return p;
}

}  // namespace stf::test
