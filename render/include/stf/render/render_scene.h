// The fixed scene of `stf render`: a sphere of homogeneous medium at the origin (index
// matched, so paths cross its boundary unbent), a pinhole camera on the -z axis, a uniform sky
// and a small bright sun. Radiance is picked up only where a path leaves the sphere.
#pragma once

#include <cmath>

#include <stf/vec3.h>

#include "stf/core/table.h"

namespace stf::render {

// The medium is core's Medium (table.h): sigma_s, sigma_a, g and the sphere's radius.

inline constexpr double kSkyRadiance = 1;
inline constexpr double kSunRadiance = 50;
inline constexpr double kSunHalfAngleDegrees = 5;
inline constexpr double kFieldOfViewDegrees = 40;  // vertical
inline constexpr double kCameraDistance = 4;       // in sphere radii, on the -z axis

// Radiance arriving from direction w (a path leaving the scene heading w).
inline double sky_radiance(const Vec3& w) {
  static const Vec3 sun = normalize({1, 1, -1});
  static const double cos_sun = std::cos(kSunHalfAngleDegrees * kPi / 180);
  return dot(w, sun) >= cos_sun ? kSunRadiance : kSkyRadiance;
}

struct Ray {
  Vec3 origin, direction;
};

// The camera ray through image position (px, py) in pixels: x to the right, y down, (0, 0)
// the top-left corner of the image.
inline Ray camera_ray(double px, double py, int width, int height, double radius) {
  const double half = std::tan(kFieldOfViewDegrees * kPi / 360);
  const double sx = (2 * px / width - 1) * half * width / height;
  const double sy = (1 - 2 * py / height) * half;
  return {{0, 0, -kCameraDistance * radius}, normalize({sx, sy, 1})};
}

// Where the ray first meets the sphere of `radius` at the origin; false when it misses.
inline bool enter_sphere(const Ray& ray, double radius, Vec3& entry) {
  const Vec3& o = ray.origin;
  const double b = dot(o, ray.direction);
  const double c = dot(o, o) - radius * radius;
  const double disc = b * b - c;
  if (disc <= 0 || b >= 0) return false;
  const double t = -b - std::sqrt(disc);
  entry = o + t * ray.direction;
  return true;
}

}  // namespace stf::render
