// Holes in triangle meshes (boundary_loops, mesh.h), each filled with flat triangles that run
// its rim's edges the other way, so that every edge ends in two triangles that agree on which
// side is outside.
#include "stf/geometry/mesh_repair.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

namespace stf::geometry {

namespace {

using Triangle = std::array<std::uint32_t, 3>;
using EdgeSet = std::unordered_set<std::uint64_t>;

std::uint64_t edge_key(std::uint32_t from, std::uint32_t to) { return (std::uint64_t(from) << 32) | to; }
std::uint64_t undirected_key(std::uint32_t a, std::uint32_t b) { return edge_key(std::min(a, b), std::max(a, b)); }

std::string where(const Vec3& v) { return fmt::format("({:g}, {:g}, {:g})", v.x, v.y, v.z); }

// As placed() rounds: the new vertex is written to OBJ and read back as the same float.
Vec3 at_float_precision(const Vec3& v) {
  volatile float x = float(v.x), y = float(v.y), z = float(v.z);
  return {x, y, z};
}

// Why `mesh` cannot be closed by adding triangles alone, or "": an index out of range, an edge
// in three or more triangles, or two triangles on an edge that run it the same way.
std::string unclosable(const TriangleMesh& mesh) {
  std::unordered_map<std::uint64_t, int> uses;  // undirected edge -> triangles
  for (const Triangle& t : mesh.triangles)
    for (int e = 0; e < 3; ++e) {
      const std::uint32_t a = t[std::size_t(e)], b = t[std::size_t((e + 1) % 3)];
      if (a >= mesh.vertices.size()) return fmt::format("a triangle names vertex {}, of {}", a + 1, mesh.vertices.size());
      ++uses[undirected_key(a, b)];
    }
  std::unordered_map<std::uint64_t, std::size_t> owner;  // directed edge -> its triangle
  for (std::size_t k = 0; k < mesh.triangles.size(); ++k)
    for (int e = 0; e < 3; ++e) {
      const std::uint32_t a = mesh.triangles[k][std::size_t(e)], b = mesh.triangles[k][std::size_t((e + 1) % 3)];
      const auto [it, added] = owner.try_emplace(edge_key(a, b), k);
      if (added) continue;
      const std::string edge = fmt::format("the edge from {} to {}", where(mesh.vertices[a]), where(mesh.vertices[b]));
      if (const int n = uses[undirected_key(a, b)]; n > 2)
        return fmt::format("{} is in {} triangles (triangles {} and {} among them): holes are filled only where "
                           "every edge has at most two triangles; the mesh is not cut apart",
                           edge, n, it->second + 1, k + 1);
      return fmt::format("triangles {} and {} both run {} the same way: they disagree on which side is "
                         "outside; triangles are not turned over",
                         it->second + 1, k + 1, edge);
    }
  return "";
}

// A hole's rim seen along its Newell normal: 2D points, counter-clockwise where the rim runs the
// way the new triangles will.
struct FlatRim {
  std::vector<std::uint32_t> vertices;  // the rim, in the new triangles' order
  std::vector<Vec3> points;             // their positions
  std::vector<double> x, y;
  Vec3 centroid;
  Frame frame;
};

double turn(const FlatRim& r, std::size_t a, std::size_t b, std::size_t c) {
  return (r.x[b] - r.x[a]) * (r.y[c] - r.y[a]) - (r.y[b] - r.y[a]) * (r.x[c] - r.x[a]);
}

// The shape of the triangle a b c: twice its area over the sum of its squared edges, as
// mesh_error measures a degenerate one, seen in the plane and in space (the smaller); 0 when it
// turns the wrong way. 1e-9 keeps well clear of mesh_error's 1e-12.
double shape(const FlatRim& r, std::array<std::size_t, 3> i) {
  const auto [a, b, c] = i;
  const double twice_area = turn(r, a, b, c);
  const auto flat_edge = [&](std::size_t p, std::size_t q) {
    return (r.x[q] - r.x[p]) * (r.x[q] - r.x[p]) + (r.y[q] - r.y[p]) * (r.y[q] - r.y[p]);
  };
  const double flat = twice_area / (flat_edge(a, b) + flat_edge(b, c) + flat_edge(c, a));
  const Vec3 &pa = r.points[a], &pb = r.points[b], &pc = r.points[c];
  const double space = length(cross(pb - pa, pc - pa)) / (dot(pb - pa, pb - pa) + dot(pc - pb, pc - pb) + dot(pa - pc, pa - pc));
  const double q = std::min(flat, space);
  return twice_area > 0 && q > 1e-9 ? q : 0;
}

FlatRim flat_rim(const BoundaryLoop& loop, const std::vector<Vec3>& v) {
  FlatRim r;
  r.vertices.assign(loop.rbegin(), loop.rend());  // the new triangles run the rim backwards
  const std::size_t n = r.vertices.size();
  Vec3 sum{0, 0, 0}, normal{0, 0, 0};
  double rim = 0;
  for (std::uint32_t i : r.vertices) sum += v[i];
  r.centroid = sum / double(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 a = v[r.vertices[i]] - r.centroid, b = v[r.vertices[(i + 1) % n]] - r.centroid;
    normal += cross(a, b);  // Newell's normal, about the centroid for precision
    rim += length(b - a);
  }
  if (!(length(normal) > 1e-9 * rim * rim))
    throw std::runtime_error(fmt::format("the hole of {} edges about {} has no mean plane: its rim encloses no area "
                                         "seen from any side",
                                         n, where(r.centroid)));
  r.frame = Frame::around(normalize(normal));
  for (std::uint32_t i : r.vertices) {
    r.points.push_back(v[i]);
    const Vec3 p = r.frame.to_local(v[i] - r.centroid);
    r.x.push_back(p.x);
    r.y.push_back(p.y);
  }
  return r;
}

// The remaining rim as a ring of positions in FlatRim.
struct Ring {
  std::vector<std::size_t> prev, next;
  std::size_t head = 0, size = 0;
};

// The corners of the ring that do not turn left: where no corner lies in an ear, no reflex one
// does (a convex corner inside brings a reflex one with it), so only these need testing.
std::vector<std::size_t> reflex_corners(const FlatRim& r, const Ring& ring) {
  std::vector<std::size_t> out;
  std::size_t j = ring.head;
  for (std::size_t k = 0; k < ring.size; ++k, j = ring.next[j])
    if (!(turn(r, ring.prev[j], j, ring.next[j]) > 0)) out.push_back(j);
  return out;
}

// Whether no reflex corner other than its own lies in or on the triangle at `i`.
bool empty_ear(const FlatRim& r, const Ring& ring, std::size_t i, const std::vector<std::size_t>& reflex) {
  const std::size_t a = ring.prev[i], c = ring.next[i];
  for (std::size_t j : reflex) {
    if (j == a || j == i || j == c) continue;
    if (turn(r, a, i, j) >= 0 && turn(r, i, c, j) >= 0 && turn(r, c, a, j) >= 0) return false;
  }
  return true;
}

// The best-shaped ear of the ring whose new edge is not yet an edge of the mesh, or -1. Only
// reflex corners are tested against each ear, so a convex rim takes time in its size squared.
std::ptrdiff_t best_ear(const FlatRim& r, const Ring& ring, const EdgeSet& edges) {
  const std::vector<std::size_t> reflex = reflex_corners(r, ring);
  std::ptrdiff_t best = -1;
  double best_shape = 0;
  std::size_t i = ring.head;
  for (std::size_t k = 0; k < ring.size; ++k, i = ring.next[i]) {
    const std::size_t a = ring.prev[i], c = ring.next[i];
    const double s = shape(r, {a, i, c});
    if (s <= best_shape) continue;
    if (ring.size > 3 && edges.count(undirected_key(r.vertices[a], r.vertices[c]))) continue;
    if (!empty_ear(r, ring, i, reflex)) continue;
    best = std::ptrdiff_t(i);
    best_shape = s;
  }
  return best;
}

// Ear clipping: true with the triangles in `added` when every ear could be cut.
bool ear_clipped(const FlatRim& r, EdgeSet& edges, std::vector<Triangle>& added) {
  const std::size_t n = r.vertices.size();
  Ring ring{std::vector<std::size_t>(n), std::vector<std::size_t>(n), 0, n};
  for (std::size_t i = 0; i < n; ++i) {
    ring.prev[i] = (i + n - 1) % n;
    ring.next[i] = (i + 1) % n;
  }
  std::vector<std::uint64_t> diagonals;
  while (ring.size >= 3) {
    const std::ptrdiff_t ear = best_ear(r, ring, edges);
    if (ear < 0) break;
    const std::size_t i = std::size_t(ear), a = ring.prev[i], c = ring.next[i];
    added.push_back({r.vertices[a], r.vertices[i], r.vertices[c]});
    diagonals.push_back(undirected_key(r.vertices[a], r.vertices[c]));
    edges.insert(diagonals.back());
    ring.next[a] = c;
    ring.prev[c] = a;
    ring.head = c;
    --ring.size;
  }
  if (ring.size < 3) return true;
  for (std::uint64_t d : diagonals) edges.erase(d);
  added.clear();
  return false;
}

// A fan about the rim's centroid (a new vertex, index `centre`): true when every triangle
// turns the rim's way and none is degenerate.
bool fanned(const FlatRim& r, std::uint32_t centre, std::vector<Triangle>& added) {
  FlatRim with_centre = r;
  with_centre.vertices.push_back(centre);
  with_centre.points.push_back(at_float_precision(r.centroid));
  with_centre.x.push_back(0);
  with_centre.y.push_back(0);
  const std::size_t n = r.vertices.size();
  for (std::size_t i = 0; i < n; ++i) {
    if (shape(with_centre, {i, (i + 1) % n, n}) <= 0) return false;
    added.push_back({r.vertices[i], r.vertices[(i + 1) % n], centre});
  }
  return true;
}

void fill_hole(const BoundaryLoop& loop, ClosedMesh& out, EdgeSet& edges) {
  const FlatRim r = flat_rim(loop, out.mesh.vertices);
  std::vector<Triangle> added;
  if (!ear_clipped(r, edges, added)) {
    const auto centre = std::uint32_t(out.mesh.vertices.size());
    if (!fanned(r, centre, added))
      throw std::runtime_error(fmt::format("the hole of {} edges about {} cannot be filled with flat triangles: its "
                                           "rim folds over itself seen along its mean normal",
                                           loop.size(), where(r.centroid)));
    out.mesh.vertices.push_back(at_float_precision(r.centroid));
    ++out.fans;
  }
  out.mesh.triangles.insert(out.mesh.triangles.end(), added.begin(), added.end());
  out.triangles_added += added.size();
  ++out.holes;
}

}  // namespace

ClosedMesh close_holes(const TriangleMesh& mesh) {
  if (std::string why = unclosable(mesh); !why.empty()) throw std::runtime_error(why);
  ClosedMesh out{mesh};
  EdgeSet edges;  // every edge of the mesh, so that no new diagonal repeats one
  for (const Triangle& t : mesh.triangles)
    for (int e = 0; e < 3; ++e) edges.insert(undirected_key(t[std::size_t(e)], t[std::size_t((e + 1) % 3)]));
  for (const BoundaryLoop& loop : boundary_loops(mesh)) fill_hole(loop, out, edges);
  return out;
}

}  // namespace stf::geometry
