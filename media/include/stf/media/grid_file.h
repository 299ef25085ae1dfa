// Density grid files written from values: .npy (float32, C order) or .vdb (through the grid codec
// module and OpenVDB, media/grid_codec.h), placed so that DensityGrid::read gives back the field
// DensityGrid::from_values makes of the same values and bounds.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "stf/media/box.h"

namespace stf::media {

enum class GridFormat { npy, vdb };

// The format a file name asks for, by its extension (.npy or .vdb, any case); nothing for another.
std::optional<GridFormat> grid_format(const std::string& path);

// Loads what writing `format` takes (for .vdb the grid codec module), so that a command can say
// it is missing before its work rather than after it. Throws std::runtime_error in one line.
void load_grid_writer(GridFormat format);

// Writes values [n^3] in C order, value [i, j, k] at the centre of voxel (i, j, k) of `bounds` cut
// into n^3 voxels (DensityGrid::from_values' convention), as `format`:
// - .npy: float32, shape [n, n, n], to be read with these bounds;
// - .vdb: the FloatGrid `density`, value [i, j, k] at index (i, j, k), the voxels > 0 active, and
//   the linear index-to-world map that puts index (i, j, k) at that voxel centre.
// Read back, the two give the same density within the bounds, to float rounding. Outside them
// the .npy field is 0 and the .vdb field falls to 0 over the next half voxel, unless the
// outermost layer of values is 0: then both are 0 there.
// Throws std::invalid_argument in one line where the values are not n^3, negative or not finite,
// or the bounds empty; std::runtime_error "PATH: why" where the file cannot be written (then it
// may be cut: write to a temporary and rename it into place, as stf's commands do).
void write_grid(const std::string& path, GridFormat format, std::vector<float> values, int n,
                const Box& bounds);
// The same, the format by the extension; another extension is a std::invalid_argument.
void write_grid(const std::string& path, std::vector<float> values, int n, const Box& bounds);

}  // namespace stf::media
