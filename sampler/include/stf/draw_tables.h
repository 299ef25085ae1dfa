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

  int lobes = 0;
  std::vector<double> lobe_cdf;      // vmf: [bins * lobes]
  std::vector<AliasTable> cells;     // sh: per bin, over its equal-area cells (their masses)
  std::vector<OutwardBin> outward;   // hemispherical lobes: each bin's outward factor, else empty
  OnceScattered once;                // when the model has a once-scattered part
};

// The lobe that u in [0, 1) picks by weight from a bin's running sums of its `lobes` lobe
// weights: the count of sums at or below u, without branches, in one cache line. A lobe of zero
// weight is never picked but as the last (rounding). (The caller passes the bin's sums and
// count: reading them through the shared tables costs 2% of a stride, bench/stride_cost.)
inline int pick_lobe(const double* sums, int lobes, double u) {
  int k = 0;
  for (int j = 0; j + 1 < lobes; ++j) k += sums[j] <= u;
  return k;
}

// The draw tables of `m`, shared.
inline std::shared_ptr<const DrawTables> make_draw_tables(const StfModel& m) { return std::make_shared<const DrawTables>(m); }

}  // namespace stf
