#include "stf/geometry/mesh.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

namespace stf::geometry {

namespace {

// Each coordinate rounded to float through a volatile: GCC 12 (-O2 and up, with its SLP
// vectoriser) drops a double -> float -> double round trip that it pairs into one vector, and
// placed() then left x and y unrounded.
double at_float_precision(double x) {
  volatile float f = float(x);
  return f;
}
Vec3 at_float_precision(const Vec3& v) { return {at_float_precision(v.x), at_float_precision(v.y), at_float_precision(v.z)}; }

}  // namespace

namespace {

// A position's hash, with -0 and +0 alike (as == has them).
struct PositionHash {
  std::size_t operator()(const Vec3& v) const {
    const std::hash<double> h;
    return h(v.x + 0.0) ^ (h(v.y + 0.0) * 0x9e3779b97f4a7c15ULL) ^ (h(v.z + 0.0) * 0xc2b2ae3d27d4eb4fULL);
  }
};
struct SamePosition {
  bool operator()(const Vec3& a, const Vec3& b) const { return a.x == b.x && a.y == b.y && a.z == b.z; }
};

}  // namespace

TriangleMesh welded(const TriangleMesh& mesh) {
  TriangleMesh out;
  std::unordered_map<Vec3, std::uint32_t, PositionHash, SamePosition> index;
  index.reserve(mesh.vertices.size());
  std::vector<std::uint32_t> renumber(mesh.vertices.size());
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Vec3& v = mesh.vertices[i];
    auto [it, added] = index.try_emplace(v, std::uint32_t(out.vertices.size()));
    if (added) out.vertices.push_back(v);
    renumber[i] = it->second;
  }
  out.triangles.reserve(mesh.triangles.size());
  for (const auto& t : mesh.triangles) out.triangles.push_back({renumber[t[0]], renumber[t[1]], renumber[t[2]]});
  return out;
}

namespace {

std::string where(const Vec3& v) { return fmt::format("({:g}, {:g}, {:g})", v.x, v.y, v.z); }

std::string vertex_error(const TriangleMesh& mesh) {
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Vec3& v = mesh.vertices[i];
    if (!(std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z)))
      return fmt::format("vertex {} is not finite", i + 1);
  }
  for (std::size_t k = 0; k < mesh.triangles.size(); ++k)
    for (std::uint32_t i : mesh.triangles[k])
      if (i >= mesh.vertices.size()) return fmt::format("triangle {} names vertex {}, of {}", k + 1, i + 1, mesh.vertices.size());
  return "";
}

// A triangle is degenerate when a vertex repeats or its area is below 1e-12 of its edges'
// squared lengths (its largest angle within 1e-12 of 180 degrees).
std::string degenerate_error(const TriangleMesh& mesh) {
  for (std::size_t k = 0; k < mesh.triangles.size(); ++k) {
    const auto& t = mesh.triangles[k];
    const Vec3 &a = mesh.vertices[t[0]], &b = mesh.vertices[t[1]], &c = mesh.vertices[t[2]];
    const double twice_area = length(cross(b - a, c - a));
    const double edges = dot(b - a, b - a) + dot(c - b, c - b) + dot(a - c, a - c);
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0] || !(twice_area > 1e-12 * edges))
      return fmt::format("triangle {} (at {}) is degenerate", k + 1, where(a));
  }
  return "";
}

std::uint64_t edge_key(std::uint32_t from, std::uint32_t to) { return (std::uint64_t(from) << 32) | to; }

// Every edge once each way: in exactly two triangles, which agree on the orientation.
std::string edge_error(const TriangleMesh& mesh) {
  std::unordered_map<std::uint64_t, std::size_t> owner;  // directed edge -> its triangle
  owner.reserve(mesh.triangles.size() * 3);
  for (std::size_t k = 0; k < mesh.triangles.size(); ++k)
    for (int e = 0; e < 3; ++e) {
      const std::uint32_t a = mesh.triangles[k][std::size_t(e)], b = mesh.triangles[k][std::size_t((e + 1) % 3)];
      auto [it, added] = owner.try_emplace(edge_key(a, b), k);
      if (!added)
        return fmt::format("the edge from {} to {} runs the same way in triangles {} and {}: the mesh is not "
                           "consistently oriented, or more than two triangles share the edge",
                           where(mesh.vertices[a]), where(mesh.vertices[b]), it->second + 1, k + 1);
    }
  // Every hole at once, not its first edge: a user mending the mesh needs them all.
  const std::vector<BoundaryLoop> holes = boundary_loops(mesh);
  if (holes.empty()) return "";
  return "the mesh is not closed, it has " + describe_holes(mesh, holes) + "; `stf mesh close IN.obj -o OUT.obj` fills them";
}

// The open edges leaving each vertex, and the vertices in the order they were first met (so
// that the loops come out the same on every run).
struct OpenEdges {
  std::unordered_map<std::uint32_t, std::vector<std::uint32_t>> leaving;
  std::vector<std::uint32_t> starts;
};

OpenEdges open_edges(const TriangleMesh& mesh) {
  std::unordered_set<std::uint64_t> directed;
  directed.reserve(mesh.triangles.size() * 3);
  for (const auto& t : mesh.triangles)
    for (int e = 0; e < 3; ++e) directed.insert(edge_key(t[std::size_t(e)], t[std::size_t((e + 1) % 3)]));
  OpenEdges open;
  for (const auto& t : mesh.triangles)
    for (int e = 0; e < 3; ++e) {
      const std::uint32_t a = t[std::size_t(e)], b = t[std::size_t((e + 1) % 3)];
      if (directed.count(edge_key(b, a))) continue;
      auto& out = open.leaving[a];
      if (out.empty()) open.starts.push_back(a);
      out.push_back(b);
    }
  for (auto& [vertex, out] : open.leaving) std::reverse(out.begin(), out.end());  // taken from the back
  return open;
}

// Follows open edges from `start` until every one leaving it is used. Each vertex has as many
// open edges in as out, so the chain can stop only at `start`; where it comes back to a vertex
// it already passed, the part since then is a loop, cut off at once.
void chain_from(std::uint32_t start, OpenEdges& open, std::vector<BoundaryLoop>& loops) {
  std::vector<std::uint32_t> path{start};
  std::unordered_map<std::uint32_t, std::size_t> at{{start, 0}};
  while (!path.empty()) {
    std::vector<std::uint32_t>& out = open.leaving[path.back()];
    if (out.empty()) break;
    const std::uint32_t v = out.back();
    out.pop_back();
    const auto seen = at.find(v);
    if (seen == at.end()) {
      at.emplace(v, path.size());
      path.push_back(v);
      continue;
    }
    const std::size_t from = seen->second;
    loops.emplace_back(path.begin() + std::ptrdiff_t(from), path.end());
    for (std::size_t k = from + 1; k < path.size(); ++k) at.erase(path[k]);
    path.resize(from + 1);
  }
}

}  // namespace

std::vector<BoundaryLoop> boundary_loops(const TriangleMesh& mesh) {
  OpenEdges open = open_edges(mesh);
  std::vector<BoundaryLoop> loops;
  for (std::uint32_t start : open.starts)
    while (!open.leaving[start].empty()) chain_from(start, open, loops);
  return loops;
}

std::string describe_holes(const TriangleMesh& mesh, const std::vector<BoundaryLoop>& loops, std::size_t shown) {
  std::string text = fmt::format("{} hole{} (rims of edges with a triangle on one side only)", loops.size(),
                                 loops.size() == 1 ? "" : "s");
  for (std::size_t k = 0; k < loops.size() && k < shown; ++k) {
    const BoundaryLoop& loop = loops[k];
    double rim = 0;
    Vec3 centre{0, 0, 0};
    for (std::size_t i = 0; i < loop.size(); ++i) {
      rim += length(mesh.vertices[loop[(i + 1) % loop.size()]] - mesh.vertices[loop[i]]);
      centre += mesh.vertices[loop[i]];
    }
    text += fmt::format("{} {} edges, {:.3g} long, about {}", k == 0 ? ":" : ";", loop.size(), rim,
                        where(centre / double(loop.size())));
  }
  if (loops.size() > shown) text += fmt::format("; and {} more", loops.size() - shown);
  return text;
}

double Bounds::largest_side() const {
  const Vec3 e = extent();
  return std::max({e.x, e.y, e.z});
}

Bounds bounds_of(const TriangleMesh& mesh) {
  Bounds b{{HUGE_VAL, HUGE_VAL, HUGE_VAL}, {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL}};
  for (const Vec3& v : mesh.vertices) {
    b.lower = {std::min(b.lower.x, v.x), std::min(b.lower.y, v.y), std::min(b.lower.z, v.z)};
    b.upper = {std::max(b.upper.x, v.x), std::max(b.upper.y, v.y), std::max(b.upper.z, v.z)};
  }
  return b;
}

std::string obj_text(const TriangleMesh& mesh) {
  std::string out;
  // Nine digits put the decimal well inside the float's rounding interval, so that an OBJ
  // reader whose parsing is not correctly rounded still reads the same float.
  for (const Vec3& v : mesh.vertices) out += fmt::format("v {:.9g} {:.9g} {:.9g}\n", float(v.x), float(v.y), float(v.z));
  for (const auto& t : mesh.triangles) out += fmt::format("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
  return out;
}

std::string mesh_error(const TriangleMesh& mesh) {
  if (mesh.triangles.empty()) return "no triangle";
  for (auto check : {vertex_error, degenerate_error, edge_error})
    if (std::string why = check(mesh); !why.empty()) return why;
  if (!(std::abs(enclosed_volume(mesh)) > 0)) return "the mesh encloses no volume";
  return "";
}

double enclosed_volume(const TriangleMesh& mesh) {
  double six_v = 0;  // the divergence theorem over tetrahedra to the origin
  for (const auto& t : mesh.triangles)
    six_v += dot(mesh.vertices[t[0]], cross(mesh.vertices[t[1]], mesh.vertices[t[2]]));
  return six_v / 6;
}

TriangleMesh oriented_outward(TriangleMesh mesh) {
  if (enclosed_volume(mesh) < 0)
    for (auto& t : mesh.triangles) std::swap(t[1], t[2]);
  return mesh;
}

TriangleMesh placed(const TriangleMesh& mesh, double scale, const Vec3& translate) {
  TriangleMesh out = mesh;
  for (Vec3& v : out.vertices) v = at_float_precision(scale * v + translate);
  return out;
}

}  // namespace stf::geometry
