// The frame conventions of a shell transport table.
#pragma once

#include <algorithm>
#include <cmath>

#include "stf/vec3.h"

namespace stf {

// An escape as the table stores it: the exit point is rotated by -beta about z into the x-z
// plane (x >= 0), so only alpha = angle(exit point, +z) remains, and the exit direction is
// rotated with it. `point` and `direction` are world-frame (start direction +z) unit vectors.
struct ReducedExit {
  double alpha;    // in [0, pi]
  Vec3 direction;  // exit direction after the -beta rotation
};

// Distance from p inside the unit sphere along unit w to the sphere. The two forms of the root
// avoid cancellation for b > 0 and b < 0; both are computed and one selected, so loops over
// many rays stay branch-free.
inline double exit_distance(const Vec3& p, const Vec3& w) {
  double b = dot(p, w), c = dot(p, p) - 1;
  double root = std::sqrt(std::max(b * b - c, 0.0));
  double ahead = -c / (b + root), behind = root - b;
  return b > 0 ? ahead : behind;
}

// Rotates `direction` by -beta about z, beta = atan2(point.y, point.x): the exit point moves
// into the x-z plane (x >= 0). On the axis beta is undefined and nothing rotates. Branch-free.
inline Vec3 rotate_to_xz_plane(const Vec3& point, const Vec3& direction) {
  double rho2 = point.x * point.x + point.y * point.y;
  bool on_axis = rho2 == 0;
  double inv_rho = 1 / std::sqrt(on_axis ? 1.0 : rho2);
  double cb = on_axis ? 1.0 : point.x * inv_rho, sb = on_axis ? 0.0 : point.y * inv_rho;
  return {cb * direction.x + sb * direction.y, -sb * direction.x + cb * direction.y, direction.z};
}

// The table's coordinates of an escape at unit `point` with unit `direction`.
inline ReducedExit reduce_exit(const Vec3& point, const Vec3& direction) {
  double rho = std::sqrt(point.x * point.x + point.y * point.y);  // unit vector: no overflow
  // atan2 keeps alpha accurate near both poles, where acos(z) loses half the digits.
  return {std::atan2(rho, point.z), rotate_to_xz_plane(point, direction)};
}

}  // namespace stf
