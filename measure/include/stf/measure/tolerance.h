// Fitting to an error tolerance: the fewest alpha bins, the coarsest direction grid and the
// smallest model whose exit distribution is within a total variation distance of the true
// one, certified on paths the fit never saw (docs/design.md, "Fitting and error").
//
// The tolerance is measured at the resolution of the tables given, the finest considered:
// TV = 0.5 sum |p - m| over their (alpha bin, cell) pairs, p the true exit distribution given
// escape and m the model's, with alpha spread over a model bin by area as the sampler does.
// Two independent tables of one medium (different seeds) are needed: `fit` and `heldout`.
//  1. Alpha bins: the fewest groups of consecutive bins (a divisor of their number) whose
//     coarsening error, the TV between the table's distribution and the same spread evenly
//     (by area) over each group, is at most tolerance / 2.
//  2. Direction grid: likewise the coarsest nested grid (HEALPix NSIDE or the cube's N
//     halved); vMF only, since SH projection needs the cells it was asked for.
//  3. Model size: the smallest candidate whose fit on the coarsened `fit` table has a
//     certified TV bound within the tolerance; the search stops when two larger sizes in a
//     row do not lower the bound (they fit noise).
// Coarsening errors are estimated from the product of the fit table's two half-tables'
// coarsening residuals, which has no noise bias (the halves are independent). The certificate
// bounds TV by Cauchy-Schwarz: sum |p - m| <= sqrt(sum (p - m)^2 / w * sum w) for any positive
// weights, here w = max(m, t, 1 / n_t) with t the fit table's distribution and n_t its escapes (so
// a cell the model underpredicts, e.g. the uncollided exit, is weighted by its data, not by the
// model's tiny mass). The weighted sum is estimated without bias from the held-out counts
// (their noise terms subtracted; w does not depend on them) and two standard deviations are
// added. The bound may exceed 1 (then it says nothing); it is infinite without escapes. Each
// fit tried is certified at two standard deviations on the same held-out table, with no
// correction for the several tried. It is conservative: 1.4 to 1.8 times the TV measured
// against large references (docs/fit.md). It is valid for the certified model itself: that
// is the one returned, not a refit.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "stf/fit/fit_table.h"
#include "stf/model.h"
#include "stf/core/table.h"

namespace stf::measure {

// A table with its alpha bins summed in groups of `alpha_factor` (which must divide their
// number) and its cells summed into the grid `grid_levels` halvings coarser.
Table coarsen_table(const Table& t, int alpha_factor, int grid_levels);

// Bound on the TV between the exit distribution and its coarsening by (alpha_factor,
// grid_levels), estimated from the two half-tables of `t` (independent paths) with weights
// from `other`, an independent table of the same medium. Unbiased for the weighted squared
// distance under the square root; noisy when the tables are small.
double coarsening_tv(const Table& t, const Table& other, int alpha_factor, int grid_levels);

struct Certificate {
  double tv_bound = 0;  // upper bound on the TV distance to the true exit distribution
  double chi2 = 0;      // unbiased estimate of sum (p - m)^2 / w
  double chi2_sd = 0;   // its standard deviation
};

// Why `heldout` cannot certify a model of `table` (it must be independent of it: another seed,
// and of the same medium, grid and alpha bins), or "" when it can.
std::string heldout_error(const Table& table, const Table& heldout);

// Certifies a model fitted to (a coarsening of) `fit` against `heldout`, a table it was not
// fitted to: the model's alpha bins must be groups of the tables'. `settings` gives the threads.
Certificate certify(const StfModel& model, const Table& fit, const Table& heldout,
                    const fit::FitSettings& settings = {});

struct ToleranceFit {
  StfModel model;
  fit::FitReport report;
  Table fitted;  // the coarsened table the model was fitted to
  int alpha_factor = 1, grid_levels = 0, size = 0;
  Certificate certificate;
  bool met = false;                              // certificate within the tolerance
  std::vector<std::pair<int, double>> attempts;  // (size, TV bound) of each fit tried
  // Lifted lobes (lvmf) that missed the tolerance where hemispherical ones were kept: the lifted
  // lobes' bound; else -1.
  double lifted_bound = -1;
};

// `settings` gives the model kind and the sizes to try: vmf:auto / sh:auto all of
// auto_candidates; vmf:K / sh:L those below K (L) and K (L) itself. When nothing meets the
// tolerance the best certified fit is returned with met = false. Lifted lobes (lvmf) that miss
// it are fitted again as hemispherical lobes (hvmf), and these are kept where they meet it or
// have the lower bound: a sphere then strides with retries rather than outside the tolerance.
// With settings.run.cancel set the result must be thrown away.
ToleranceFit fit_to_tolerance(const Table& fit, const Table& heldout, double tolerance,
                              const fit::FitSettings& settings);

}  // namespace stf::measure
