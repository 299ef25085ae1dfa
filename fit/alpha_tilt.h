// How the escapes after two or more collisions are spread inside each alpha bin: the tilt of
// stf/tilt.h, fitted by maximum likelihood to the table's sub-bin counts
// (/escape/multiple_sub_half).
#pragma once

#include <vector>

#include "table.h"

namespace stf::fit {

// The tilt maximising sum_k counts[k] log tilt_mass(tilt, edges[k], edges[k + 1]), edges
// increasing in [0, 1]; 0 when there are no counts, clamped to +-kMaxTilt.
double tilt_from_counts(const std::vector<double>& edges, const std::vector<double>& counts);

// Per alpha bin of `t`, from both halves or one (half 0 or 1); empty when the table has no
// sub-bin tallies.
std::vector<double> fit_alpha_tilts(const Table& t, int half = -1);

// Of the tilted density's mass on [u0, u1] of a blended bin (StfModel::alpha_blend), the parts
// drawn from the bin's own direction density and from its lower and upper neighbours' (weight
// |u - 1/2| on each side of the middle). They sum to tilt_mass(tilt, u0, u1).
struct BlendShares {
  double own = 0, lower = 0, upper = 0;
};
BlendShares blend_shares(double tilt, double u0, double u1);

// The direction distribution over cells of bin b of a blended model: `own` (bin b's) mixed
// with its neighbours' as blend_shares over the whole bin; a missing neighbour's share stays
// with `own`.
std::vector<double> blended_cells(double tilt, const std::vector<double>& own, const std::vector<double>* lower,
                                  const std::vector<double>* upper);

// `t`'s sub-bin tallies for its alpha bins grouped by `f` (coarsen_table): the sub-bins of a
// group's bins, in order, with their edges as fractions of the group's area.
void group_sub_bins(const Table& t, int f, Table& coarse);

}  // namespace stf::fit
