// How the escapes after two or more collisions are spread inside each alpha bin: the tilt of
// stf/tilt.h, fitted by maximum likelihood to the table's sub-bin counts
// (/escape/multiple_sub_half).
#pragma once

#include <functional>
#include <utility>
#include <vector>

#include "stf/model.h"

#include "stf/core/table.h"

namespace stf::fit {

// The share of bin b of `reference` in the probability of the group of f bins holding it (b /
// f): its area on the unit sphere, since a sampler spreads alpha uniformly in cos(alpha) within
// a bin.
double area_share(const Table& reference, int b, int f);

// The tilt maximising sum_k counts[k] log tilt_mass(tilt, edges[k], edges[k + 1]), edges
// increasing in [0, 1]; 0 when there are no counts, clamped to +-kMaxTilt.
double tilt_from_counts(const std::vector<double>& edges, const std::vector<double>& counts);

// Per alpha bin of `t`, from both halves or one (half 0 or 1); empty when the table has no
// sub-bin tallies.
std::vector<double> fit_alpha_tilts(const Table& t, int half = -1);
// The same from sub-bin counts laid out as the table's ([alpha_bins * sub_bins]), e.g. a
// smoothed marginal's expected ones (smooth_alpha_marginal).
std::vector<double> tilts_from_sub_counts(const Table& t, const std::vector<double>& sub_counts);

// Of the smooth part's mass on the area fractions [u0, u1] of bin b, the shares drawn from each
// bin's direction density: StfModel::blend_weights integrated under the bin's tilted density.
// (bin, share) pairs that sum to tilt_mass(tilt of b, u0, u1); one pair, (b, mass), unblended.
std::vector<std::pair<int, double>> blend_shares(const StfModel& m, int b, double u0, double u1);

// The cell distribution the whole of bin b averages to: each blended bin j's distribution as it
// lies in bin b (`cells_in_b(j)`), mixed by blend_shares over [0, 1].
using CellsInBin = std::function<const std::vector<double>&(int j)>;
std::vector<double> blended_cells(const StfModel& m, int b, const CellsInBin& cells_in_b);

// `t`'s sub-bin tallies for its alpha bins grouped by `f` (coarsen_table): the sub-bins of a
// group's bins, in order, with their edges as fractions of the group's area.
void group_sub_bins(const Table& t, int f, Table& coarse);

}  // namespace stf::fit
