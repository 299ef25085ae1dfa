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

Table mirror_folded(const Table& t) {
  if (t.uncollided_half[0] < 0) return t;
  const std::unique_ptr<DirectionGrid> grid = make_grid(t.grid);
  const std::vector<std::int64_t> image = mirror_cells(*grid);
  if (image.empty()) return t;
  Table f = t;
  const std::size_t pole = std::size_t(grid->cell({0, 0, 1})), cells = std::size_t(t.cells);
  for (int h = 0; h < 2; ++h) {
    std::vector<double> w = t.weight_half[h];
    w[pole] -= t.uncollided_half[h];  // bin 0's delta: it stays where it is
    for (std::size_t b = 0; b < std::size_t(t.alpha_bins); ++b)
      for (std::size_t c = 0; c < cells; ++c)
        f.weight_half[h][b * cells + c] = 0.5 * (w[b * cells + c] + w[b * cells + std::size_t(image[c])]);
    f.weight_half[h][pole] += t.uncollided_half[h];
  }
  // Keys are 2 (bin cells + cell) + half.
  f.once.clear();
  for (const auto& [key, count] : t.once) {
    const std::uint64_t i = key >> 1, cell = i % cells;
    const std::uint64_t mirrored = 2 * (i - cell + std::uint64_t(image[cell])) + (key & 1);
    f.once[key] += 0.5 * count;
    f.once[mirrored] += 0.5 * count;
  }
  return f;
}

}  // namespace stf::fit
