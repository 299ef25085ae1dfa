// A procedural cumulus: a density grid to render and to test the trackers on. A few overlapping
// blobs (a wide body on a flat base, flanks beside it, towers rising along +y, the scenes' up),
// each of density exactly 1 over its core and falling smoothly to 0 at its edge, the edges
// swollen and eroded by fractal noise that never reaches the cores. So the density is exactly 1
// over a large region (constant density, where strides through the medium are exact), and 0 on
// the outermost voxel layer (so the field read back from .npy and from .vdb is the same:
// stf/media/grid_file.h).
#pragma once

#include <cstdint>
#include <vector>

#include "stf/core/parallel.h"
#include "stf/media/box.h"

namespace stf::media {

// Voxels per edge. Below 16 the falloff is a voxel or two thick and the cloud a lump; 1024^3
// values are 4 GiB.
constexpr int kMinCloudSize = 16, kMaxCloudSize = 1024;

struct Cumulus {
  int size = 0;  // voxels per edge
  Box bounds;    // the cube of side 1 centred at the origin
  // [size^3] in [0, 1], C order: value [i, j, k] at the centre of voxel (i, j, k) of `bounds`,
  // (-0.5 + (i + 1/2) / size, ...), as DensityGrid::from_values and .npy files take them.
  std::vector<float> values;
};

// The cumulus of `seed` on size^3 voxels: one continuous field, sampled at the voxel centres, so
// a seed gives the same cloud at every size. Computed on run.threads threads (the values do not
// depend on them); cancelled (run.cancel), the values are incomplete. Throws
// std::invalid_argument for a size outside [kMinCloudSize, kMaxCloudSize].
Cumulus cumulus(int size, std::uint64_t seed, const RunContext& run = {});

}  // namespace stf::media
