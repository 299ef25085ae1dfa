// Closed triangle meshes that bound a medium: read from OBJ, checked, placed in the scene, and
// the small procedural shapes the tests and scenes use.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "stf/vec3.h"

namespace stf::geometry {

// Vertices are held at float precision (each a float widened to double): the mesh Embree
// traces and the one distances are measured on are the same mesh.
struct TriangleMesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;  // counter-clockwise seen from outside
};

struct Bounds {
  Vec3 lower, upper;
  Vec3 extent() const { return upper - lower; }
  double largest_side() const;
};
Bounds bounds_of(const TriangleMesh& mesh);

// Reads an OBJ file (faces of more than three vertices fanned into triangles; vertices at the
// same position joined). Throws std::runtime_error naming the file when it cannot be read or
// holds no triangle.
TriangleMesh read_obj(const std::string& path);

// The mesh with vertices at the same position joined (an OBJ may repeat a position per face or
// per texture seam) and the triangles renumbered.
TriangleMesh welded(const TriangleMesh& mesh);

// Writes `mesh` as OBJ (vertices and faces only), for the shipped procedural meshes.
std::string obj_text(const TriangleMesh& mesh);

// Why `mesh` cannot bound a medium, naming the first offending element, or "" when it can:
// every vertex finite, no triangle degenerate (zero area, or a vertex repeated), closed and
// consistently oriented (every edge in exactly two triangles, once each way; either way round,
// see oriented_outward) and enclosing a volume. Self-intersections are not looked for.
std::string mesh_error(const TriangleMesh& mesh);

// The mesh with its triangles turned the other way when they face inward (negative volume);
// a closed consistently oriented mesh is one or the other.
TriangleMesh oriented_outward(TriangleMesh mesh);

// Signed volume enclosed (positive for outward orientation).
double enclosed_volume(const TriangleMesh& mesh);

// x -> scale * x + translate, each vertex rounded to float precision.
TriangleMesh placed(const TriangleMesh& mesh, double scale, const Vec3& translate);

// Procedural closed meshes, outward oriented, centred at the origin.
TriangleMesh icosphere(double radius, int subdivisions);
TriangleMesh torus(double major_radius, double minor_radius, int rings, int sides);
// A box of half-extents `half` whose edges and corners are rounded with `radius`
// (radius < min(half)), `segments` quads per quarter circle.
TriangleMesh rounded_box(const Vec3& half, double radius, int segments);

}  // namespace stf::geometry
