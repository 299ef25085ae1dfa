// What a render counts of its paths: collisions, strides, rays by what they are for.
#pragma once

#include <cstdint>

#include "stf/render/pixel_rng.h"

namespace stf::render {

// What a ray cast against a scene's surfaces is for (PathCounters::rays_by).
enum RayKind {
  kCameraRay,       // a camera path's first ray
  kOutsideRay,      // a path outside media after it left one or the ground
  kFlightRay,       // a flight in a medium that may reach its boundary
  kShadowCollision, // a leg of a shadow ray from a collision
  kShadowExit,      // a leg of a shadow ray from a stride's exit
  kShadowGround,    // a leg of a shadow ray from the ground
  kRayKinds
};
inline constexpr const char* kRayKindNames[kRayKinds] = {"camera", "outside", "flight", "shadow_collision",
                                                         "shadow_exit", "shadow_ground"};

struct PathCounters {
  std::int64_t collisions = 0;        // free flights ended by a real collision
  std::int64_t null_collisions = 0;   // tentative collisions of delta tracking that were not real (grids)
  std::int64_t strides = 0;           // jumps through a precomputed sphere
  std::int64_t distance_queries = 0;  // free radii asked of a mesh's grid or Embree
  std::int64_t shadow_rays = 0;       // next-event estimation toward the lights
  std::int64_t rays = 0;              // at the surfaces: flights, paths outside, shadow legs
  std::int64_t ideal_collisions = 0;  // inside ideal strides (PathOptions::ideal_strides)
  std::int64_t once_scattered_exits = 0;  // strides left once scattered: no shadow ray there
  std::int64_t rays_by[kRayKinds] = {};    // rays by what they are for
  void count_ray(RayKind kind) { ++rays, ++rays_by[kind]; }
};

// Paths whose throughput falls below this play Russian roulette (survivors carry exactly it),
// so no path is followed long after it stopped mattering and none is cut off with bias.
inline constexpr double kRouletteBelow = 0.25;

// False when the path ends in Russian roulette; a survivor's throughput is raised to the
// threshold.
inline bool survives_roulette(double& throughput, PixelRng& rng) {
  if (throughput >= kRouletteBelow) return true;
  if (rng.uniform() * kRouletteBelow >= throughput) return false;
  throughput = kRouletteBelow;
  return true;
}

}  // namespace stf::render
