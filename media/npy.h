// NumPy .npy files (format versions 1.0, 2.0 and 3.0): float32 or float64, little-endian, C
// order, shape [nx, ny, nz]. Parsed and written here, with no library: the header is a Python
// dict literal.
#pragma once

#include <string>

#include "lattice.h"

namespace stf::media {

// The array of `path` placed in `bounds` (value [i, j, k] at its voxel's centre, the field clipped
// to the bounds). `fits` checks the size from the header, before the values are read. Throws
// grid_error.
Lattice read_npy(const std::string& path, const Box& bounds, FitsCheck fits);

// Writes values [dims] (C order) as float32 in format 1.0, as numpy.save would. Throws grid_error
// in one line, the file then cut or absent.
void write_npy(const std::string& path, const std::vector<float>& values, const Dims& dims);

// What an .npy header says.
struct NpyHeader {
  std::string descr;  // "<f4"
  bool fortran_order = false;
  std::vector<std::int64_t> shape;
};

// Parses the header's dict literal; throws grid_error(path, ...) on what it cannot read.
NpyHeader parse_npy_header(const std::string& path, const std::string& text);

}  // namespace stf::media
