// The majorant grid: bounds on the density over blocks of cells (the bricks, kBrick^3 cells).
#include <algorithm>
#include <cmath>
#include <limits>

#include "stf/media/density_grid.h"

namespace stf::media {

// Each block's min and max over the lattice values at its cells' corners, lattice points
// b edge - 1 .. (b + 1) edge - 1 on each axis; the padding's corners are zeros.
std::vector<DensityGrid::Brick> DensityGrid::block_ranges(int edge, std::array<int, 3>& counts) const {
  for (int a = 0; a < 3; ++a) counts[std::size_t(a)] = int((dims_[std::size_t(a)] + 1 + edge - 1) / edge);  // cells -1 .. n - 1
  std::vector<Brick> blocks(std::size_t(counts[0]) * std::size_t(counts[1]) * std::size_t(counts[2]));
  for (int bx = 0; bx < counts[0]; ++bx)
    for (int by = 0; by < counts[1]; ++by)
      for (int bz = 0; bz < counts[2]; ++bz) {
        const int b[3] = {bx, by, bz};
        std::int64_t lo[3], hi[3];
        bool padded = false;
        for (std::size_t a = 0; a < 3; ++a) {
          lo[a] = std::int64_t(b[a]) * edge - 1, hi[a] = lo[a] + edge;
          padded = padded || lo[a] < 0 || hi[a] >= dims_[a];
          lo[a] = std::max<std::int64_t>(lo[a], 0), hi[a] = std::min(hi[a], dims_[a] - 1);
        }
        float least = padded ? 0.0f : std::numeric_limits<float>::infinity(), most = 0;
        for (std::int64_t i = lo[0]; i <= hi[0]; ++i)
          for (std::int64_t j = lo[1]; j <= hi[1]; ++j) {
            const float* row = &values_[std::size_t((i * dims_[1] + j) * dims_[2])];
            for (std::int64_t k = lo[2]; k <= hi[2]; ++k) least = std::min(least, row[k]), most = std::max(most, row[k]);
          }
        blocks[(std::size_t(bx) * std::size_t(counts[1]) + std::size_t(by)) * std::size_t(counts[2]) + std::size_t(bz)] = {least, most};
      }
  return blocks;
}

void DensityGrid::build_bricks() { bricks_ = block_ranges(kBrick, brick_counts_); }

}  // namespace stf::media
