// Holes in triangle meshes (boundary_loops, mesh.h) filled with flat triangles that turn the
// way their neighbours do (`stf mesh close`).
#pragma once

#include <cstddef>

#include "stf/geometry/mesh.h"

namespace stf::geometry {

// What close_holes did.
struct ClosedMesh {
  TriangleMesh mesh;               // the input's vertices and triangles first, then what was added
  std::size_t holes = 0;           // loops filled
  std::size_t triangles_added = 0;
  std::size_t fans = 0;            // holes filled by a fan about a new centre vertex
};

// `mesh` with every hole filled. Each hole is triangulated by ear clipping in the plane of its
// Newell normal (no new vertex, the best-shaped ear first), or, where no ear can be cut, by a
// fan about its centroid if every fan triangle turns the rim's way in that plane. New triangles
// run each rim edge the other way to its triangle, so they turn as their neighbours do; no new
// edge repeats an edge of the mesh. Throws std::runtime_error with one line when it cannot:
// an edge in three or more triangles, two triangles that disagree on orientation, or a hole
// neither way fills. The result is not checked here: mesh_error(result) says whether it bounds.
ClosedMesh close_holes(const TriangleMesh& mesh);

}  // namespace stf::geometry
