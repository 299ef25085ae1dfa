#include "stf/media/grid_file.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <stdexcept>
#include <utility>

#include "grid_codec.h"
#include "lattice.h"
#include "npy.h"

namespace stf::media {

std::optional<GridFormat> grid_format(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".npy") return GridFormat::npy;
  if (ext == ".vdb") return GridFormat::vdb;
  return std::nullopt;
}

void load_grid_writer(GridFormat format) {
  if (format == GridFormat::vdb) grid_codec();  // .npy is written here
}

namespace {

// The values on their lattice, refused (std::invalid_argument) where DensityGrid would refuse
// them: a file written must read back, so it holds some density, none negative or not finite.
Lattice checked_lattice(const std::string& path, std::vector<float> values, int n,
                        const Box& bounds) {
  try {
    const std::size_t side = n > 0 ? std::size_t(n) : 0;
    if (side == 0 || values.size() != side * side * side)
      throw grid_error(path, std::to_string(values.size()) + " values are not a " +
                                 std::to_string(n) + "^3 grid");
    check_bounds(path, bounds);
    Lattice lattice;
    lattice.source = path;
    lattice.dims = {n, n, n};
    lattice.values = std::move(values);
    check_values(lattice);
    if (std::none_of(lattice.values.begin(), lattice.values.end(), [](float v) { return v > 0; }))
      throw grid_error(path, "the values hold no non-zero density");
    place_in_bounds(lattice, bounds);
    return lattice;
  } catch (const std::runtime_error& e) {
    throw std::invalid_argument(e.what());
  }
}

}  // namespace

void write_grid(const std::string& path, GridFormat format, std::vector<float> values, int n,
                const Box& bounds) {
  const Lattice lattice = checked_lattice(path, std::move(values), n, bounds);
  if (format == GridFormat::npy)
    write_npy(path, lattice.values, lattice.dims);
  else
    grid_codec().write_vdb(path, lattice);
}

void write_grid(const std::string& path, std::vector<float> values, int n, const Box& bounds) {
  const std::optional<GridFormat> format = grid_format(path);
  if (!format)
    throw std::invalid_argument(path +
                                ": a density grid is written as .vdb or .npy, by its extension");
  write_grid(path, *format, std::move(values), n, bounds);
}

}  // namespace stf::media
