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

  std::vector<double> lobe_cdf;      // vmf: [bins * lobes], running sums of each bin's lobe weights
  std::vector<AliasTable> cells;     // sh: per bin, over its equal-area cells (their masses)
  std::vector<OutwardBin> outward;   // hemispherical lobes: each bin's outward factor, else empty
  OnceScattered once;                // when the model has a once-scattered part
};

// The draw tables of `m`, shared.
inline std::shared_ptr<const DrawTables> make_draw_tables(const StfModel& m) { return std::make_shared<const DrawTables>(m); }

}  // namespace stf
