// The procedural meshes of the tests and scenes. Each is built from a grid or a subdivided solid
// whose shared vertices are computed from the same numbers, so that welding joins them exactly.
#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "stf/geometry/mesh.h"
#include "stf/geometry/shipped_meshes.h"

namespace stf::geometry {

namespace {

// Rounds to float precision and joins equal positions (as read_obj does).
TriangleMesh finished(const TriangleMesh& mesh) { return oriented_outward(welded(placed(mesh, 1.0, {0, 0, 0}))); }

// Two triangles of the quad (a, b, c, d), counter-clockwise.
void add_quad(TriangleMesh& m, std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d) {
  m.triangles.push_back({a, b, c});
  m.triangles.push_back({a, c, d});
}

TriangleMesh icosahedron() {
  const double t = (1 + std::sqrt(5.0)) / 2;
  TriangleMesh m;
  m.vertices = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  m.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                 {3, 8, 9},  {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  return m;
}

// Each triangle into four, the new vertices at the edges' midpoints pushed onto the unit sphere.
TriangleMesh subdivided(const TriangleMesh& m) {
  TriangleMesh out;
  out.vertices = m.vertices;
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> middle;
  auto mid = [&](std::uint32_t a, std::uint32_t b) {
    auto [it, added] = middle.try_emplace({std::min(a, b), std::max(a, b)}, std::uint32_t(out.vertices.size()));
    if (added) out.vertices.push_back(normalize(out.vertices[a] + out.vertices[b]));
    return it->second;
  };
  for (const auto& t : m.triangles) {
    const std::uint32_t ab = mid(t[0], t[1]), bc = mid(t[1], t[2]), ca = mid(t[2], t[0]);
    out.triangles.insert(out.triangles.end(), {{t[0], ab, ca}, {t[1], bc, ab}, {t[2], ca, bc}, {ab, bc, ca}});
  }
  return out;
}

// Nodes along one axis of a rounded box: the rounding's tangents (equal angles from 0 to 45
// degrees on each face), then the flat part, symmetric about 0.
std::vector<double> box_nodes(double half, double radius, int segments) {
  std::vector<double> up;  // from the flat part's end outward
  for (int k = 0; k <= segments; ++k)
    up.push_back(k == segments ? half : (half - radius) + radius * std::tan(k * (kPi / 4) / segments));
  std::vector<double> nodes;
  for (auto it = up.rbegin(); it != up.rend(); ++it) nodes.push_back(-*it);
  for (double u : up) nodes.push_back(u);
  return nodes;
}

// A point of the box's surface moved onto the rounded box: its nearest point of the inner box
// (shrunk by the radius) plus the radius towards it.
Vec3 rounded(const Vec3& p, const Vec3& inner, double radius) {
  const Vec3 core{std::clamp(p.x, -inner.x, inner.x), std::clamp(p.y, -inner.y, inner.y), std::clamp(p.z, -inner.z, inner.z)};
  return core + radius * normalize(p - core);
}

}  // namespace

TriangleMesh icosphere(double radius, int subdivisions) {
  TriangleMesh m = icosahedron();
  for (Vec3& v : m.vertices) v = normalize(v);
  for (int i = 0; i < subdivisions; ++i) m = subdivided(m);
  for (Vec3& v : m.vertices) v = radius * v;
  return finished(m);
}

TriangleMesh torus(double major_radius, double minor_radius, int rings, int sides) {
  TriangleMesh m;
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < sides; ++j) {
      const double u = 2 * kPi * i / rings, v = 2 * kPi * j / sides;
      const double r = major_radius + minor_radius * std::cos(v);
      m.vertices.push_back({r * std::cos(u), minor_radius * std::sin(v), r * std::sin(u)});
    }
  auto at = [&](int i, int j) { return std::uint32_t((i % rings) * sides + (j % sides)); };
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < sides; ++j) add_quad(m, at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j));
  return finished(m);
}

TriangleMesh rounded_box(const Vec3& half, double radius, int segments) {
  const std::array<std::vector<double>, 3> nodes{box_nodes(half.x, radius, segments), box_nodes(half.y, radius, segments),
                                                 box_nodes(half.z, radius, segments)};
  const Vec3 inner = half - Vec3{radius, radius, radius};
  TriangleMesh m;
  for (int axis = 0; axis < 3; ++axis)
    for (int side : {-1, 1}) {
      const int a = (axis + 1) % 3, b = (axis + 2) % 3;  // (a, b, axis) right-handed
      const auto& na = nodes[std::size_t(a)];
      const auto& nb = nodes[std::size_t(b)];
      const std::uint32_t first = std::uint32_t(m.vertices.size());
      for (double u : na)
        for (double v : nb) {
          double p[3];
          p[axis] = side > 0 ? nodes[std::size_t(axis)].back() : nodes[std::size_t(axis)].front();
          p[a] = u, p[b] = v;
          m.vertices.push_back(rounded({p[0], p[1], p[2]}, inner, radius));
        }
      const std::uint32_t w = std::uint32_t(nb.size());
      for (std::uint32_t i = 0; i + 1 < na.size(); ++i)
        for (std::uint32_t j = 0; j + 1 < w; ++j) {
          const std::uint32_t c = first + i * w + j;
          if (side > 0) add_quad(m, c, c + w, c + w + 1, c + 1);
          else add_quad(m, c, c + 1, c + w + 1, c + w);
        }
    }
  return finished(m);
}

}  // namespace stf::geometry

namespace stf::geometry {

std::vector<std::pair<std::string, TriangleMesh>> shipped_meshes() {
  return {{"icosphere.obj", icosphere(0.5, 4)},
          {"torus.obj", torus(0.35, 0.15, 64, 32)},
          {"rounded_box.obj", rounded_box({0.5, 0.35, 0.25}, 0.08, 4)},
          {"thin_plate.obj", rounded_box({0.5, 0.04, 0.4}, 0.02, 3)}};
}

TriangleMesh box(const Vec3& lower, const Vec3& upper) {
  TriangleMesh m;
  for (int k = 0; k < 8; ++k)  // corner k: bit 0 picks x's upper side, bit 1 y's, bit 2 z's
    m.vertices.push_back({k & 1 ? upper.x : lower.x, k & 2 ? upper.y : lower.y, k & 4 ? upper.z : lower.z});
  // Each face's corners counter-clockwise seen from outside, as two triangles.
  const std::uint32_t faces[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
  for (const auto& f : faces) {
    m.triangles.push_back({f[0], f[1], f[2]});
    m.triangles.push_back({f[0], f[2], f[3]});
  }
  return m;
}

}  // namespace stf::geometry
