// The two ways `stf render` follows a path through the medium, behind one interface:
// BruteForce tracks every collision; ShellStrides jumps through precomputed spheres where one
// fits and tracks collisions only where none does (docs/render.md).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <stf/lookup.h>
#include <stf/pack.h>
#include <stf/sampler.h>

#include "stf/hg.h"
#include "stf/render/pixel_rng.h"
#include "stf/render/render_scene.h"

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
  std::int64_t collisions = 0;        // free flights ended by a collision
  std::int64_t strides = 0;           // jumps through a precomputed sphere
  std::int64_t distance_queries = 0;  // free radii asked of a mesh's grid or Embree (scenes)
  std::int64_t shadow_rays = 0;       // next-event estimation toward the sun (scenes)
  std::int64_t rays = 0;              // at the surfaces (scenes): flights, paths outside, shadow legs
  std::int64_t ideal_collisions = 0;  // inside ideal strides (scenes, PathOptions::ideal_strides)
  std::int64_t once_scattered_exits = 0;  // strides left once scattered: no shadow ray there (scenes)
  std::int64_t rays_by[kRayKinds] = {};    // rays by what they are for
  void count_ray(RayKind kind) { ++rays, ++rays_by[kind]; }
};

// Paths whose throughput falls below this play Russian roulette (survivors carry exactly it),
// so no path is followed long after it stopped mattering and none is cut off with bias.
inline constexpr double kRouletteBelow = 0.25;

// What both methods share: one free flight from x along w, then either the path leaves the
// sphere (true: it is heading w) or it collides, its throughput scaled by the albedo and w
// redrawn from Henyey-Greenstein.
class CollisionWalk {
 public:
  explicit CollisionWalk(const Medium& m);
  bool leaves_after_flight(Vec3& x, Vec3& w, double& throughput, PixelRng& rng) const;

 private:
  double inv_sigma_t_, albedo_, radius2_;
  HgParams<double> hg_;
};

// False when the path ends in Russian roulette; a survivor's throughput is raised to the
// threshold.
bool survives_roulette(double& throughput, PixelRng& rng);

class Method {
 public:
  virtual ~Method() = default;
  // Radiance carried back along a camera path that enters the medium at `entry` heading
  // `direction`.
  virtual double radiance(const Vec3& entry, const Vec3& direction, PixelRng& rng, PathCounters& counters) const = 0;
};

class BruteForce final : public Method {
 public:
  explicit BruteForce(const Medium& m) : walk_(m) {}
  double radiance(const Vec3& entry, const Vec3& direction, PixelRng& rng, PathCounters& counters) const override;

 private:
  CollisionWalk walk_;
};

// Strides through the precomputed spheres in `pack` whose albedo and g are the medium's
// (their names are ignored); with none, it is BruteForce draw for draw.
class ShellStrides final : public Method {
 public:
  ShellStrides(const Medium& m, const std::vector<PackEntry>& pack);
  double radiance(const Vec3& entry, const Vec3& direction, PixelRng& rng, PathCounters& counters) const override;
  int spheres() const { return spheres_.size(); }
  double smallest_tau() const { return spheres_.size() > 0 ? spheres_.tau(0) : 0.0; }
  double largest_tau() const { return spheres_.size() > 0 ? spheres_.tau(spheres_.size() - 1) : 0.0; }

 private:
  // The largest sphere that fits at x: sphere i (ascending radius) fits where |x| <= R - r_i,
  // that is |x|^2 <= limit2_[i], so no square root waits on the path's last step.
  int fitting_sphere(const Vec3& x) const;

  CollisionWalk walk_;
  SphereLookup spheres_;  // the pack's spheres of this medium's albedo and g
  std::vector<double> limit2_, radius_;  // per sphere: (R - r_i)^2 (-1 if it cannot fit), r_i
};

// Mean collisions of a path from the centre of a sphere of optical radius `tau` (scattering
// with g, never absorbed) until it leaves: what one stride through that sphere replaces. A
// fixed-seed walk of `paths` paths (its standard error about sqrt(tau^2 / paths) at most).
double crossing_collisions(double tau, double g, int paths = 20000);

// The smallest optical radius of the ladder 1, 2, 4, ... 16 whose crossing takes more collisions
// than a stride costs (`stride_cost`, in collisions): smaller spheres cost more than they save.
double smallest_paying_tau(double g, double stride_cost);

// The spheres of `stf render`'s pack for a medium (docs/render.md, "Ladders from the stride
// cost"): optical radii from `smallest` by `ratio`, with radii (in the medium's units) in
// [radius_min, radius_max]: up to the medium's radius or tau 128, whichever is smaller.
struct PackLadder {
  double smallest, ratio, radius_min, radius_max;
};
PackLadder pack_ladder(const Medium& m);
// The same for a medium whose largest free radius is `room` (an object of a render scene):
// radius_max < radius_min when no sphere that pays fits.
PackLadder stride_ladder(const Medium& m, double room);

}  // namespace stf::render
