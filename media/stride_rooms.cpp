#include "stf/media/stride_rooms.h"

#include <algorithm>

namespace stf::media {

namespace {

// The cube within k + 1 of a block is the union of the cubes within k of its 27 neighbours: one
// step of a 3 x 3 x 3 min/max filter, axis by axis (beyond the grid the density is 0).
void widen(std::vector<DensityGrid::Brick>& cubes, const std::array<int, 3>& n) {
  const auto index = [&](int x, int y, int z) {
    return (std::size_t(x) * std::size_t(n[1]) + std::size_t(y)) * std::size_t(n[2]) + std::size_t(z);
  };
  for (std::size_t a = 0; a < 3; ++a) {
    const std::vector<DensityGrid::Brick> before = cubes;
    for (int x = 0; x < n[0]; ++x)
      for (int y = 0; y < n[1]; ++y)
        for (int z = 0; z < n[2]; ++z) {
          int c[3] = {x, y, z};
          DensityGrid::Brick& cube = cubes[index(x, y, z)];
          for (const int d : {-1, 1}) {
            c[a] += d;
            const bool inside = c[a] >= 0 && c[a] < n[a];
            const DensityGrid::Brick next = inside ? before[index(c[0], c[1], c[2])] : DensityGrid::Brick{};
            cube.min = std::min(cube.min, next.min), cube.max = std::max(cube.max, next.max);
            c[a] -= d;
          }
        }
  }
}

}  // namespace

StrideRooms stride_rooms(const DensityGrid& grid, double tolerance, int most) {
  StrideRooms r;
  std::vector<DensityGrid::Brick> cubes = grid.block_ranges(StrideRooms::kBlock, r.counts);
  const auto keeps = [&](const DensityGrid::Brick& b) { return b.min > 0 && b.max <= (1 + tolerance) * b.min; };
  r.room.assign(cubes.size(), -1);
  bool any = false;
  for (std::size_t i = 0; i < cubes.size(); ++i)
    if (keeps(cubes[i])) r.room[i] = 0, any = true;
  for (int k = 1; any && k <= std::min(most, 127); ++k) {  // cubes only grow: once none keeps it, none will
    widen(cubes, r.counts);
    any = false;
    for (std::size_t i = 0; i < cubes.size(); ++i)
      if (keeps(cubes[i])) r.room[i] = std::int8_t(k), any = true;
  }
  return r;
}

}  // namespace stf::media
