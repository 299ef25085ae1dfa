// The majorant grid: bounds on the density over bricks of kBrick^3 cells, and over balls.
#include <algorithm>
#include <cmath>
#include <limits>

#include "stf/media/density_grid.h"

namespace stf::media {

namespace {

double axis(const Vec3& v, int a) { return a == 0 ? v.x : a == 1 ? v.y : v.z; }

}  // namespace

// Each brick's min and max over the lattice values at its cells' corners, lattice points
// b kBrick - 1 .. (b + 1) kBrick - 1 on each axis; the padding's corners are zeros.
void DensityGrid::build_bricks() {
  for (int a = 0; a < 3; ++a) brick_counts_[a] = int((dims_[a] + 1 + kBrick - 1) / kBrick);  // cells -1 .. n - 1
  bricks_.assign(std::size_t(brick_counts_[0]) * std::size_t(brick_counts_[1]) * std::size_t(brick_counts_[2]), Brick{});
  for (int bx = 0; bx < brick_counts_[0]; ++bx)
    for (int by = 0; by < brick_counts_[1]; ++by)
      for (int bz = 0; bz < brick_counts_[2]; ++bz) {
        const int b[3] = {bx, by, bz};
        std::int64_t lo[3], hi[3];
        bool padded = false;
        for (int a = 0; a < 3; ++a) {
          lo[a] = std::int64_t(b[a]) * kBrick - 1, hi[a] = lo[a] + kBrick;
          padded = padded || lo[a] < 0 || hi[a] >= dims_[a];
          lo[a] = std::max<std::int64_t>(lo[a], 0), hi[a] = std::min(hi[a], dims_[a] - 1);
        }
        float least = padded ? 0.0f : std::numeric_limits<float>::infinity(), most = 0;
        for (std::int64_t i = lo[0]; i <= hi[0]; ++i)
          for (std::int64_t j = lo[1]; j <= hi[1]; ++j) {
            const float* row = &values_[std::size_t((i * dims_[1] + j) * dims_[2])];
            for (std::int64_t k = lo[2]; k <= hi[2]; ++k) least = std::min(least, row[k]), most = std::max(most, row[k]);
          }
        bricks_[(std::size_t(bx) * std::size_t(brick_counts_[1]) + std::size_t(by)) * std::size_t(brick_counts_[2]) +
                std::size_t(bz)] = {least, most};
      }
}

// The ball's lattice image is an ellipsoid whose extent along lattice axis a is radius times the
// length of row a of the world-to-lattice matrix; the bricks that box overlaps bound it, and
// where the box leaves the support the density there, 0, joins the range.
std::pair<double, double> DensityGrid::range_over_ball(const Vec3& centre, double radius) const {
  const Vec3 c = to_lattice(centre);
  if (!(radius >= 0) || !std::isfinite(radius) || !std::isfinite(c.x + c.y + c.z)) return {0, max_density_};
  int first[3], last[3];
  bool reaches_zero = false;
  for (int a = 0; a < 3; ++a) {
    const auto& row = to_lattice_[std::size_t(a)];
    const double h = radius * std::sqrt(row[0] * row[0] + row[1] * row[1] + row[2] * row[2]);
    const double s_lo = axis(lattice_support_.lower, a), s_hi = axis(lattice_support_.upper, a);
    const double lo = std::max(axis(c, a) - h, s_lo), hi = std::min(axis(c, a) + h, s_hi);
    if (lo > hi) return {0, 0};  // the ball misses the support
    reaches_zero = reaches_zero || axis(c, a) - h < s_lo || axis(c, a) + h > s_hi;
    first[a] = std::clamp(int(std::floor((lo + 1) / kBrick)), 0, brick_counts_[a] - 1);
    last[a] = std::clamp(int(std::floor((hi + 1) / kBrick)), 0, brick_counts_[a] - 1);
  }
  double least = reaches_zero ? 0 : std::numeric_limits<double>::infinity(), most = 0;
  for (int bx = first[0]; bx <= last[0]; ++bx)
    for (int by = first[1]; by <= last[1]; ++by)
      for (int bz = first[2]; bz <= last[2]; ++bz) {
        const Brick& b = brick(bx, by, bz);
        least = std::min(least, double(b.min)), most = std::max(most, double(b.max));
      }
  return {least, most};
}

}  // namespace stf::media
