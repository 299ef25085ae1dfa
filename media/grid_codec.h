// The OpenVDB side of density grids, in a module of its own (libstf_grid_codec.so) that the media
// library loads the first time a .vdb file is read or written: linked in, libopenvdb cost every
// stf command 36 ms of startup (media/CMakeLists.txt has the measurement).
#pragma once

#include <string>

#include "lattice.h"

namespace stf::media {

struct GridCodec {
  // Reads the density grid of a .vdb file into `lattice` (all but `source`): the float grid named
  // `density`, else the only float grid, densely over its active voxels' bounding box. Calls
  // `fits(path, dims)` (which throws when a dense copy would not fit) before reading the values,
  // from the file's metadata where it has the bounding box. Throws grid_error in one line.
  void (*read_vdb)(const std::string& path, FitsCheck fits, Lattice& lattice);
  // Writes `lattice` (dims, values, to_world) as a .vdb file: a FloatGrid named `density`, value
  // [i, j, k] at index (i, j, k), active where it is > 0 (what read_vdb takes for density), with
  // the index-to-world map to_world. Throws grid_error in one line, the file then cut or absent.
  void (*write_vdb)(const std::string& path, const Lattice& lattice);
};

// The module, loaded once: from $STF_GRID_CODEC when set (and then only from there), else where
// the image codec would be (stf/core/plugin.h). Throws std::runtime_error naming it and why.
const GridCodec& grid_codec();

}  // namespace stf::media

// The module's one export.
extern "C" const stf::media::GridCodec* stf_grid_codec();
