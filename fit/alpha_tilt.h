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

// Per alpha bin of `t`, from both halves (empty when the table has no sub-bin tallies).
std::vector<double> fit_alpha_tilts(const Table& t);

// `t`'s sub-bin tallies for its alpha bins grouped by `f` (coarsen_table): the sub-bins of a
// group's bins, in order, with their edges as fractions of the group's area.
void group_sub_bins(const Table& t, int f, Table& coarse);

}  // namespace stf::fit
