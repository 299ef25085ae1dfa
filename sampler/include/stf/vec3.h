// Small vector type shared by every stage (the sampler library depends on nothing else).
#pragma once

#include <cmath>

namespace stf {

inline constexpr double kPi = 3.14159265358979323846;

struct Vec3 {
  double x = 0, y = 0, z = 0;
};

inline double dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline double length(const Vec3& v) { return std::sqrt(dot(v, v)); }
inline Vec3 normalize(const Vec3& v) {
  double inv = 1.0 / length(v);
  return {v.x * inv, v.y * inv, v.z * inv};
}
// v turned by `angle` about +y, from +z towards +x: the way the exit point turns as alpha grows.
inline Vec3 turn_about_y(const Vec3& v, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return {c * v.x + s * v.z, v.y, c * v.z - s * v.x};
}
inline Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

}  // namespace stf
