// The once-scattered part of the exit distribution binned exactly into a table's layout, so
// that eval, the tolerance certificate and plots compare it cell by cell with a table.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "stf/core/grid.h"

namespace stf::fit {

struct OnceScatteredCells {
  std::vector<double> bin_mass;  // [bins]: the part's share in each alpha bin; they sum to 1
  std::vector<std::vector<std::pair<std::int64_t, double>>> cells;  // per bin: (cell, share of the part)
  double probability = 0;  // of escaping after exactly one collision, divided by the albedo
};

// Exit directions (sin theta, 0, mu) lie on a half great circle, booked half on each side of the
// plane y' = 0 as the walk books them. For each collision depth s of a Gauss-Legendre rule the
// mu axis is cut where the exit angle crosses an alpha edge and where the circle crosses a cell
// edge; each piece, one (bin, cell), is integrated over the HG quantile u.
OnceScatteredCells bin_once_scattered(double tau, double g, const std::vector<double>& alpha_edges,
                                      const DirectionGrid& grid);

}  // namespace stf::fit
