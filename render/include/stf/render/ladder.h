// Which spheres pay for a medium: the stride cost against the collisions a sphere's crossing
// replaces, and the ladder of optical radii a render's pack holds (docs/render.md, "Ladders from
// the stride cost").
#pragma once

#include "stf/core/table.h"
#include "stf/hg.h"
#include "stf/render/pixel_rng.h"
#include "stf/vec3.h"

namespace stf::render {

// A free flight from x along w in a sphere of homogeneous medium about the origin, then either
// the path leaves the sphere (true: it is heading w) or it collides, its throughput scaled by the
// albedo and w redrawn from Henyey-Greenstein: the walk crossing_collisions counts, and the
// benches' reference loop.
class CollisionWalk {
 public:
  explicit CollisionWalk(const Medium& m);
  bool leaves_after_flight(Vec3& x, Vec3& w, double& throughput, PixelRng& rng) const;

 private:
  double inv_sigma_t_, albedo_, radius2_;
  HgParams<double> hg_;
};

// Mean collisions of a path from the centre of a sphere of optical radius `tau` (scattering
// with g, never absorbed) until it leaves: what one stride through that sphere replaces. A
// fixed-seed walk of `paths` paths (its standard error about sqrt(tau^2 / paths) at most).
double crossing_collisions(double tau, double g, int paths = 20000);

// The smallest optical radius of the ladder 1, 2, 4, ... 16 whose crossing takes more collisions
// than a stride costs (`stride_cost`, in collisions): smaller spheres cost more than they save.
double smallest_paying_tau(double g, double stride_cost);

// The spheres of `stf render`'s pack for a medium: optical radii from `smallest` by `ratio`, with
// radii (in the medium's units) in [radius_min, radius_max]: up to the medium's radius or tau 128,
// whichever is smaller.
struct PackLadder {
  double smallest, ratio, radius_min, radius_max;
};
PackLadder pack_ladder(const Medium& m);
// The same for a medium whose largest free radius is `room` (an object of a render scene):
// radius_max < radius_min when no sphere that pays fits.
PackLadder stride_ladder(const Medium& m, double room);

}  // namespace stf::render
