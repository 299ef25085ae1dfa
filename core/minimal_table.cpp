#include "stf/core/minimal_table.h"

#include <H5Cpp.h>

#include <bit>
#include <cmath>
#include <stdexcept>

#include "stf/core/grid.h"
#include "stf/core/h5io.h"
#include "stf/core/rng.h"

namespace stf {

void lay_out(Table& t, const DirectionGrid& grid, int alpha_bins) {
  t.grid = grid.spec();
  t.alpha_bins = alpha_bins;
  t.cells = grid.cell_count();
  t.alpha_edges.clear();
  for (int i = 0; i <= alpha_bins; ++i) t.alpha_edges.push_back(kPi * i / alpha_bins);
  t.alpha_edges.back() = kPi;
  t.direction.clear();
  for (std::int64_t c = 0; c < t.cells; ++c) {
    const Vec3 v = grid.centre(c);
    t.direction.push_back({v.x, v.y, v.z});
  }
  t.solid_angle = grid.solid_angles();
}

std::uint64_t binomial_half(std::uint64_t n, std::uint64_t& state) {
  std::uint64_t ones = 0;
  for (; n >= 64; n -= 64) ones += std::uint64_t(std::popcount(splitmix64(state)));
  if (n > 0) ones += std::uint64_t(std::popcount(splitmix64(state) & ((std::uint64_t(1) << n) - 1)));
  return ones;
}

void split_halves(const std::vector<double>& weight, std::uint64_t seed, Table& t) {
  bool whole = true;
  for (double w : weight) whole = whole && w == std::floor(w) && w < 0x1p53;
  for (auto& half : t.weight_half) half.assign(weight.size(), 0.0);
  t.halves = whole ? Halves::kThinned : Halves::kEven;
  const std::size_t cells = std::size_t(t.cells);
  for (std::size_t b = 0; b < std::size_t(t.alpha_bins); ++b) {
    // One stream per alpha bin: the halves do not depend on how the table is read.
    std::uint64_t state = seed ^ (0x9e3779b97f4a7c15ull * (b + 1));
    for (std::size_t i = b * cells; i < (b + 1) * cells; ++i) {
      const double w = weight[i];
      t.weight_half[0][i] = whole ? double(binomial_half(std::uint64_t(w), state)) : 0.5 * w;
      t.weight_half[1][i] = w - t.weight_half[0][i];
    }
  }
}

std::string grid_of_cells(std::int64_t cells) {
  for (std::int64_t nside = 1; nside <= kMaxNside; nside *= 2)
    if (12 * nside * nside == cells) return "healpix:" + std::to_string(nside);
  const auto n = std::int64_t(std::llround(std::sqrt(double(cells) / 6)));
  if (n >= 1 && n <= kMaxCubeN && 6 * n * n == cells) return "csc:" + std::to_string(n);
  return "";
}

std::string grid_mismatch(const std::string& spec, const std::vector<std::array<double, 3>>& direction) {
  // The count first: a grid spec can name billions of cells.
  if (const std::int64_t cells = grid_cell_count(spec); cells != std::int64_t(direction.size()))
    return spec + " has " + std::to_string(cells) + " cells, /grid/direction " + std::to_string(direction.size());
  std::unique_ptr<DirectionGrid> grid = make_grid(spec);
  // Float32 centres are good to ~1e-7; a wrong numbering is off by a cell (>= 1e-3 on every grid stf allows).
  constexpr double kTolerance = 1e-5;
  for (std::size_t c = 0; c < direction.size(); ++c) {
    const Vec3 centre = grid->centre(std::int64_t(c));
    const double dx = centre.x - direction[c][0], dy = centre.y - direction[c][1], dz = centre.z - direction[c][2];
    if (!(std::sqrt(dx * dx + dy * dy + dz * dz) < kTolerance))
      return "/grid/direction of cell " + std::to_string(c) + " is not the centre of " + spec +
             "'s cell (HEALPix in RING order, the cube as stf numbers it)";
  }
  return "";
}

std::string minimal_table_file(const Table& layout, const std::vector<double>& weight,
                               const std::function<void(H5::H5File&)>& attributes, const char* name) {
  try {
    H5::Exception::dontPrint();
    h5::MemoryFile memory;
    H5::H5File& file = memory.file();
    attributes(file);
    const hsize_t bins = hsize_t(layout.alpha_bins), cells = hsize_t(layout.cells);
    H5::Group escape = file.createGroup("/escape");
    h5::put_dataset(escape, name, {bins, cells}, weight.data());
    h5::put_dataset(escape, "alpha_edges", {bins + 1}, layout.alpha_edges.data());
    H5::Group grid = file.createGroup("/grid");
    h5::put_dataset(grid, "direction", {cells, 3}, layout.direction.front().data());
    h5::put_dataset(grid, "solid_angle", {cells}, layout.solid_angle.data());
    escape.close();
    grid.close();
    return memory.bytes();
  } catch (const H5::Exception& e) {
    throw std::runtime_error("cannot write a table: " + e.getDetailMsg());
  }
}

}  // namespace stf
