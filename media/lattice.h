// What a reader of a grid file hands to DensityGrid, and the checks every reader shares.
#pragma once

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "stf/media/box.h"
#include "stf/vec3.h"

namespace stf::media {

using Dims = std::array<std::int64_t, 3>;

// Values at the lattice points (i, j, k), C order, and where they are.
struct Lattice {
  std::string source;  // the file, or "values"
  Dims dims{};
  std::vector<float> values;
  std::array<std::array<double, 4>, 3> to_world{};  // x = A u + t: columns 0-2 are A, 3 is t
  Box clip{};                                       // lattice coordinates; beyond it the field is 0
  // How a bad value is named: "[i, j, k]" for arrays, "index (x, y, z)" (lattice point + origin)
  // for .vdb files.
  Dims index_origin{};
  bool vdb_index = false;
};

// "SOURCE: what" as the one-line error every reader throws.
inline std::runtime_error grid_error(const std::string& source, const std::string& what) {
  return std::runtime_error(source + ": " + what);
}

// A check that throws grid_error when a dense copy of a lattice of `dims` would not fit in
// memory; readers call it before reading the values.
using FitsCheck = void (*)(const std::string& source, const Dims& dims);

// Throws grid_error naming the first value (C order) that is negative or not finite.
void check_values(const Lattice& lattice);

// Lattice coordinates of a flat C-order index, as "[i, j, k]" or "index (x, y, z)".
std::string name_index(const Lattice& lattice, std::size_t flat);

// .npy's placement: lattice point (i, j, k) at the centre of voxel (i, j, k) of `bounds` cut into
// dims voxels, the field clipped to the bounds.
void place_in_bounds(Lattice& lattice, const Box& bounds);

// "lower < upper, both finite" on each axis, else one line naming the axis.
void check_bounds(const std::string& source, const Box& bounds);

}  // namespace stf::media
