// The boundaries of a scene's media as Embree sees them: rays against the triangles
// (RTC_SCENE_FLAG_ROBUST, so a ray through a vertex or along an edge does not slip between
// triangles) and the exact distance to the nearest triangle (rtcPointQuery), object k being
// mesh k. Const and thread-safe once made.
#pragma once

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include "stf/geometry/mesh.h"

namespace stf::geometry {

struct Hit {
  bool found = false;
  double t = 0;    // distance along the ray
  int object = -1;
  int triangle = -1;
  Vec3 normal;     // the triangle's outward unit normal
};

class Boundary {
 public:
  // Meshes must be closed and outward oriented (mesh_error, oriented_outward); throws
  // std::runtime_error when Embree cannot be set up.
  explicit Boundary(std::vector<TriangleMesh> meshes);
  ~Boundary();
  Boundary(const Boundary&) = delete;
  Boundary& operator=(const Boundary&) = delete;

  // The first triangle along origin + t direction (unit) for t in (0, t_max).
  Hit intersect(const Vec3& origin, const Vec3& direction, double t_max = HUGE_VAL) const;
  // A lower bound of the distance from x to the nearest triangle, within a relative 2e-6 of it.
  double distance(const Vec3& x) const;
  // Whether x is inside object k (the parity of crossings of a ray from x).
  bool inside(const Vec3& x, int object) const;
  // Where a ray that crossed the boundary at `point` (normal n) goes on from, heading
  // `direction`: moved off the surface to the side it heads for, by a margin above Embree's
  // rounding, so that it does not find the same triangle again.
  Vec3 spawn(const Vec3& point, const Vec3& n, const Vec3& direction) const;

  int objects() const { return int(meshes_.size()); }
  const TriangleMesh& mesh(int k) const { return meshes_[std::size_t(k)]; }
  double scale() const { return scale_; }  // the largest side of all meshes' bounds

 private:
  struct Embree;
  std::vector<TriangleMesh> meshes_;
  double scale_ = 0;
  std::unique_ptr<Embree> embree_;
};

// A point just off the surface at `point` (normal n) on the side `direction` heads for, by
// 1e-5 of the larger of the scene's size `scale` and the point's coordinates: above Embree's
// float rounding, so that a ray from there does not find the same surface again. Inline: every
// crossing of a surface takes one.
inline Vec3 off_surface(const Vec3& point, const Vec3& n, const Vec3& direction, double scale) {
  const double margin = 1e-5 * std::max(scale, std::max({std::abs(point.x), std::abs(point.y), std::abs(point.z)}));
  return point + (dot(direction, n) >= 0 ? margin : -margin) * n;
}

// The squared distance from p to the triangle (a, b, c).
double squared_distance_to_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace stf::geometry
