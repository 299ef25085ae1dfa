// Small vector type and orthonormal frame shared by every stage (the sampler library depends on
// nothing else). Each operator does what the component-wise expression it replaces did, in the
// same order, so results are the same to the bit.
#pragma once

#include <cmath>

namespace stf {

inline constexpr double kPi = 3.14159265358979323846;

struct Vec3 {
  double x = 0, y = 0, z = 0;
};

inline Vec3 operator+(const Vec3& a, const Vec3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3 operator-(const Vec3& a, const Vec3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3 operator-(const Vec3& a) { return {-a.x, -a.y, -a.z}; }
inline Vec3 operator*(const Vec3& a, double s) { return {a.x * s, a.y * s, a.z * s}; }
inline Vec3 operator*(double s, const Vec3& a) { return {s * a.x, s * a.y, s * a.z}; }
inline Vec3 operator/(const Vec3& a, double s) { return {a.x / s, a.y / s, a.z / s}; }
inline Vec3& operator+=(Vec3& a, const Vec3& b) { return a = a + b; }

inline double dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline double length(const Vec3& v) { return std::sqrt(dot(v, v)); }
inline Vec3 normalize(const Vec3& v) { return v * (1.0 / length(v)); }
inline Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
// v turned by `angle` about +y, from +z towards +x: the way the exit point turns as alpha grows.
inline Vec3 turn_about_y(const Vec3& v, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return {c * v.x + s * v.z, v.y, c * v.z - s * v.x};
}

// Unit vectors completing `n` to a right-handed orthonormal frame (Duff et al. 2017).
inline void orthonormal_basis(const Vec3& n, Vec3& b1, Vec3& b2) {
  double sign = std::copysign(1.0, n.z), a = -1 / (sign + n.z), b = n.x * n.y * a;
  b1 = {1 + sign * n.x * n.x * a, sign * b, -sign * n.x};
  b2 = {b, sign + n.y * n.y * a, -n.y};
}

// A right-handed orthonormal frame: local coordinates are the components along x, y and z.
struct Frame {
  Vec3 x{1, 0, 0}, y{0, 1, 0}, z{0, 0, 1};

  // The frame whose z is the unit vector n.
  static Frame around(const Vec3& n) {
    Frame f;
    f.z = n;
    orthonormal_basis(n, f.x, f.y);
    return f;
  }
  // By component rather than as x * v.x + y * v.y + z * v.z: -O3 vectorises the operator form
  // into other fused multiply-adds, and draws would move by an ulp.
  Vec3 to_world(const Vec3& v) const {
    return {v.x * x.x + v.y * y.x + v.z * z.x, v.x * x.y + v.y * y.y + v.z * z.y, v.x * x.z + v.y * y.z + v.z * z.z};
  }
  Vec3 to_local(const Vec3& v) const { return {dot(v, x), dot(v, y), dot(v, z)}; }
};

}  // namespace stf
