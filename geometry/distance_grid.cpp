#include "stf/geometry/distance_grid.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace stf::geometry {

DistanceGrid::DistanceGrid(const Boundary& boundary, const Bounds& region, int cells, const RunContext& run) {
  if (cells < 1 || cells > 1024) throw std::invalid_argument("a distance grid has 1 to 1024 cells along its largest side");
  const Vec3 extent = region.extent();
  cell_ = std::max(region.largest_side(), 1e-30) / cells;
  inv_cell_ = 1 / cell_;
  origin_ = region.lower;
  n_[0] = std::max(1, int(std::ceil(extent.x / cell_))), n_[1] = std::max(1, int(std::ceil(extent.y / cell_)));
  n_[2] = std::max(1, int(std::ceil(extent.z / cell_)));
  // The centre a query computes may differ from the one measured here by rounding.
  slack_ = 1e-12 * (region.largest_side() + length(region.lower) + length(region.upper));
  distance_.resize(std::size_t(n_[0]) * std::size_t(n_[1]) * std::size_t(n_[2]));
  const std::size_t row = std::size_t(n_[0]), plane = row * std::size_t(n_[1]);
  parallel_for(n_[2], run, [&](std::int64_t k, int) {
    for (int j = 0; j < n_[1]; ++j)
      for (int i = 0; i < n_[0]; ++i) {
        const double d = boundary.distance(origin_ + cell_ * Vec3{i + 0.5, j + 0.5, k + 0.5});
        float f = float(d);
        if (double(f) > d) f = std::nextafter(f, 0.0f);
        distance_[std::size_t(k) * plane + std::size_t(j) * row + std::size_t(i)] = f;
      }
  });
}

}  // namespace stf::geometry
