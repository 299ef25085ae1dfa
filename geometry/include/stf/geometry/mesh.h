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

// Reads an OBJ file strictly (obj.cpp): every `v` has three finite numbers within float range
// (a weight or an RGB colour after them is allowed and ignored), every face corner names a
// vertex defined above it (from 1, or negative from the last), faces of more than three
// vertices are fanned into triangles when convex and refused otherwise, free-form geometry is
// refused, and every other statement (vt, vn, o, g, s, l, mtllib, usemtl, ...) is skipped
// without opening any file it names. Vertices at the same position are joined. Throws
// std::runtime_error "FILE:LINE: what" (or "FILE: what") when the file is not a regular file,
// cannot be read, has a statement it cannot read exactly or holds no triangle.
TriangleMesh read_obj(const std::string& path);
// The same with every vertex as the file has it, none joined (`stf mesh close` counts the joins).
TriangleMesh read_obj_as_written(const std::string& path);

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

// The vertices of one hole's rim, in the order its open edges run in their own triangles: the
// edge from vertices[i] to vertices[i + 1] (and from the last to the first) has a triangle on
// one side only. No vertex appears twice in a loop.
using BoundaryLoop = std::vector<std::uint32_t>;

// The holes of `mesh`, whose directed edges must each be in one triangle at most (mesh_error's
// first edge test): the open edges chained into loops. Where a vertex lies on the rim of two
// holes (or twice on one) the chain is cut there, so each loop passes every vertex once.
std::vector<BoundaryLoop> boundary_loops(const TriangleMesh& mesh);

// One line on `loops`: how many, and for the first `shown` their edges, rim length and centre.
std::string describe_holes(const TriangleMesh& mesh, const std::vector<BoundaryLoop>& loops, std::size_t shown = 3);

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
// The box [lower, upper]: 8 corners, 12 triangles, outward oriented.
TriangleMesh box(const Vec3& lower, const Vec3& upper);

}  // namespace stf::geometry
