// The procedural meshes shipped in data/scenes/meshes/ (tools/make_meshes writes them; a test
// checks that the files are what these make).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "stf/geometry/mesh.h"

namespace stf::geometry {

// (file name, mesh): an icosphere of radius 0.5 (4 subdivisions), a torus (0.35 and 0.15), a
// rounded box (0.5 x 0.35 x 0.25 half-extents, radius 0.08) and a thin rounded plate
// (0.5 x 0.04 x 0.4, radius 0.02): all of largest side about 1.
std::vector<std::pair<std::string, TriangleMesh>> shipped_meshes();

}  // namespace stf::geometry
