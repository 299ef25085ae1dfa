// Small vector type and the frame conventions of a shell transport table.
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

// An escape as the table stores it: the exit point is rotated by -beta about z into the x-z
// plane (x >= 0), so only alpha = angle(exit point, +z) remains, and the exit direction is
// rotated with it. `point` and `direction` are world-frame (start direction +z) unit vectors.
struct ReducedExit {
  double alpha;    // in [0, pi]
  Vec3 direction;  // exit direction after the -beta rotation
};

// Rotates `direction` by -beta about z, beta = atan2(point.y, point.x), rho = |point.xy|.
inline Vec3 rotate_to_xz_plane(const Vec3& point, const Vec3& direction, double rho) {
  if (rho == 0) return direction;  // beta is undefined on the axis: no rotation
  double cb = point.x / rho, sb = point.y / rho;
  return {cb * direction.x + sb * direction.y, -sb * direction.x + cb * direction.y, direction.z};
}

inline ReducedExit reduce_exit(const Vec3& point, const Vec3& direction) {
  double rho = std::sqrt(point.x * point.x + point.y * point.y);  // unit vector: no overflow
  // atan2 keeps alpha accurate near both poles, where acos(z) loses half the digits.
  double alpha = std::atan2(rho, point.z);
  return {alpha, rotate_to_xz_plane(point, direction, rho)};
}

}  // namespace stf
