// Where a stride may go in a density grid at a relative tolerance: per block of kBlock^3 cells,
// how far about it the density keeps max <= (1 + tolerance) min (min > 0). Built once per grid
// and tolerance, so that a stride's ball is one load (render/medium.h): a search over the
// majorant's bricks a ball overlaps reads up to hundreds at every collision, and 8^3-cell bricks
// are too coarse for the detail strides meet (docs/studies/2026-12-media-that-vary.md).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "stf/media/density_grid.h"

namespace stf::media {

struct StrideRooms {
  // Cells per block edge: 2 resolves the density's detail a stride meets (a tau-4 sphere spans
  // a cell or two of the shipped grids) at a byte per 8 cells.
  static constexpr int kBlock = 2;
  // Block b along an axis covers lattice coordinates [b kBlock - 1, (b + 1) kBlock - 1].
  static double block_lower(int b) { return DensityGrid::block_lower(b, kBlock); }

  std::array<int, 3> counts{};
  // Per block: k >= 0 where the blocks within k of it (a cube 2k + 1 blocks a side, inside the
  // grid) keep the tolerance together, the largest such k; -1 where not even the block does.
  std::vector<std::int8_t> room;

  int at(int bx, int by, int bz) const {
    return room[(std::size_t(bx) * std::size_t(counts[1]) + std::size_t(by)) * std::size_t(counts[2]) + std::size_t(bz)];
  }
};

// The rooms of `grid` at `tolerance`, k at most `most` (at most 127): 64 blocks, 128 cells,
// beyond any stride's ball in the grids stf renders.
StrideRooms stride_rooms(const DensityGrid& grid, double tolerance, int most = 64);

}  // namespace stf::media
