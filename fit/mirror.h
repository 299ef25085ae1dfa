// The mirror symmetry of the exit distribution: the experiment is symmetric about the plane
// through the sphere's axis and the exit point, so in the exit point's frame a direction and
// its image under y -> -y are equally likely (docs/design.md). A table holds that symmetry only
// up to its noise; folding it (each cell's counts averaged with its mirror cell's) halves the
// noise a fit sees without changing what it estimates.
#pragma once

#include <cstdint>
#include <vector>

#include "stf/core/grid.h"

namespace stf::fit {

// For every cell of `grid`, the cell holding its mirror image under y -> -y; empty when the
// grid is not mirror-symmetric (some cell's image is not, to 1e-3 of a cell, a cell of the same
// solid angle).
std::vector<std::int64_t> mirror_cells(const DirectionGrid& grid);

// Each cell's count and its mirror cell's both replaced by their mean: the counts of one alpha
// bin, without the uncollided delta (a point at the pole, not a density), as a fit reads them.
void fold_over_mirror(std::vector<double>& counts, const std::vector<std::int64_t>& image);

}  // namespace stf::fit
