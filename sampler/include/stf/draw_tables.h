// The tables a model is drawn from, built once per model and shared by its samplers: the
// general ShellSampler (stf/sampler.h) and the stride form renderers stride with
// (stf/stride.h) draw from the same lobe sums, SH cells, outward factors and once-scattered part.
#pragma once

#include <memory>
#include <vector>

#include "stf/alias.h"
#include "stf/hemisphere.h"
#include "stf/model.h"
#include "stf/once_scattered.h"

namespace stf {

struct DrawTables {
  explicit DrawTables(const StfModel& m);

  // vmf: bin b's running sums of its lobe weights.
  BinSlice<const double> lobe_sums(int b) const { return bin_slice(lobe_cdf, b, lobes); }
  // The lobe of bin b that u in [0, 1) picks by weight: the count of running sums at or below
  // u, without branches, in one cache line. A lobe of zero weight is never picked but as the
  // last (rounding).
  int pick_lobe(int b, double u) const {
    const BinSlice<const double> sums = lobe_sums(b);
    int k = 0;
    for (std::size_t j = 0; j + 1 < sums.size(); ++j) k += sums[j] <= u;
    return k;
  }

  int lobes = 0;
  std::vector<double> lobe_cdf;      // vmf: [bins * lobes]
  std::vector<AliasTable> cells;     // sh: per bin, over its equal-area cells (their masses)
  std::vector<OutwardBin> outward;   // hemispherical lobes: each bin's outward factor, else empty
  OnceScattered once;                // when the model has a once-scattered part
};

// The draw tables of `m`, shared.
inline std::shared_ptr<const DrawTables> make_draw_tables(const StfModel& m) { return std::make_shared<const DrawTables>(m); }

}  // namespace stf
