// How the escapes after two or more collisions are spread over the exit angle alpha, smoothed
// across the alpha bins. A table's bin totals carry Poisson noise that no direction model can
// remove; the density of exit points is smooth in alpha, so a penalised fit to the sub-bin
// tallies (/escape/multiple_sub_half) is closer to the truth than the counts themselves.
#pragma once

#include <vector>

#include "stf/core/table.h"

namespace stf::fit {

struct AlphaMarginal {
  std::vector<double> bin_escapes;  // [alpha_bins]: expected escapes (both halves), summing to the tallied total
  std::vector<double> sub_escapes;  // [alpha_bins * sub_bins]: the same per sub-bin
  double penalty = 0;               // the roughness penalty chosen on the held-out halves
};

// The log density per unit area is a cubic B-spline in alpha with 24 knots at pi (k / 23)^2,
// dense near the pole where thin forward media put their exits; its coefficients' second
// differences are penalised (a P-spline) with the weight chosen among 1 to 1e6 in half decades
// by fitting each half of the paths and scoring the other.
// Empty (the counts are kept) when the table has no sub-bin tallies, no separate tally of the
// once-scattered escapes, or no escapes after two or more collisions in either half.
AlphaMarginal smooth_alpha_marginal(const Table& t);

}  // namespace stf::fit
