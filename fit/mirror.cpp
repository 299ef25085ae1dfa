#include "mirror.h"

#include <cmath>

#include "stf/vec3.h"

namespace stf::fit {

std::vector<std::int64_t> mirror_cells(const DirectionGrid& grid) {
  const std::int64_t cells = grid.cell_count();
  const std::vector<double> omega = grid.solid_angles();
  std::vector<std::int64_t> image(std::size_t(cells), 0);
  // The cube's centres and areas come from polynomial fits of its projection, symmetric to
  // ~1e-6 only; a grid that is not symmetric is off by a good part of a cell.
  const double cell_size = std::sqrt(4 * kPi / double(cells)), tolerance = 1e-3;
  for (std::int64_t c = 0; c < cells; ++c) {
    const Vec3 x = grid.centre(c), mirrored{x.x, -x.y, x.z};
    const std::int64_t m = grid.cell(mirrored);
    const Vec3 y = grid.centre(m);
    const double off = std::abs(y.x - mirrored.x) + std::abs(y.y - mirrored.y) + std::abs(y.z - mirrored.z);
    const double area = std::abs(omega[std::size_t(m)] - omega[std::size_t(c)]) / omega[std::size_t(c)];
    if (off > tolerance * cell_size || area > tolerance) return {};
    image[std::size_t(c)] = m;
  }
  for (std::int64_t c = 0; c < cells; ++c)
    if (image[std::size_t(image[std::size_t(c)])] != c) return {};
  return image;
}

void fold_over_mirror(std::vector<double>& counts, const std::vector<std::int64_t>& image) {
  for (std::size_t c = 0; c < counts.size(); ++c) {
    const std::size_t m = std::size_t(image[c]);
    if (m > c) counts[c] = counts[m] = 0.5 * (counts[c] + counts[m]);
  }
}

}  // namespace stf::fit
