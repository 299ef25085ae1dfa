#include "stf/render/ladder.h"

#include <algorithm>
#include <cmath>

#include <stf/math.h>

namespace stf::render {

namespace {

// w' at polar cosine `c` (sine `s`) and azimuth 2 pi u about w.
Vec3 turn(const Vec3& w, double c, double s, double u) {
  double sp, cp;
  sincos_2pi(u, sp, cp);
  return Frame::around(w).to_world({s * cp, s * sp, c});
}

}  // namespace

CollisionWalk::CollisionWalk(const Medium& m)
    : inv_sigma_t_(1 / m.sigma_t()), albedo_(m.albedo()), radius2_(m.radius * m.radius),
      hg_(HgParams<double>::make(m.g)) {}

bool CollisionWalk::leaves_after_flight(Vec3& x, Vec3& w, double& throughput, PixelRng& rng) const {
  const double t = -std::log(rng.uniform_open0()) * inv_sigma_t_;
  x += t * w;
  if (dot(x, x) > radius2_) return true;  // the sphere is convex: past the boundary means out
  throughput *= albedo_;
  const CosSin<double> cs = sample_hg(hg_, rng.uniform());
  w = turn(w, cs.cos_theta, cs.sin_theta, rng.uniform());
  return false;
}

double crossing_collisions(double tau, double g, int paths) {
  Medium m;
  m.sigma_s = 1, m.sigma_a = 0, m.g = g, m.radius = tau;
  const CollisionWalk walk(m);
  std::int64_t collisions = 0;
  for (int p = 0; p < paths; ++p) {
    PixelRng rng(0x5eed, std::uint64_t(p));
    Vec3 x{0, 0, 0}, w{0, 0, 1};
    double throughput = 1;
    while (!walk.leaves_after_flight(x, w, throughput, rng)) ++collisions;
  }
  return double(collisions) / paths;
}

double smallest_paying_tau(double g, double stride_cost) {
  double tau = 1;
  while (tau < 16 && crossing_collisions(tau, g) <= stride_cost) tau *= 2;
  return tau;
}

namespace {
// What a stride of the stride form costs, in collisions (bench/stride_cost on the small spheres
// of a render pack): spheres whose crossing takes fewer collisions than this cost more than they
// save, so the render pack starts at the smallest that takes more.
constexpr double kStrideCost = 4.5;
// Neighbouring spheres of the render pack differ by this factor. sqrt 2 raises the bound of ideal
// strides by 13-16% at a fixed stride cost, but its strides cost more (more spheres' data in the
// caches) and its packs 1.5-2.3x the precompute; in render_bench it did not pay on dense media.
constexpr double kSphereRatio = 2;
// The largest sphere of the render pack. Larger ones carry about 1% of the strides of the bench's
// media (stride_bound's shares) and, as a sphere's walk grows as tau^2, most of the precompute:
// dropping them lowers the bound of ideal strides by 2.8% at most (tau 1000, albedo 0.99999).
constexpr double kLargestSphere = 128;
}  // namespace

PackLadder pack_ladder(const Medium& m) {
  PackLadder l = stride_ladder(m, m.radius);
  l.radius_min = std::min(m.radius, l.radius_min);
  return l;
}

PackLadder stride_ladder(const Medium& m, double room) {
  const double smallest = smallest_paying_tau(m.g, kStrideCost), sigma_t = m.sigma_t();
  return {smallest, kSphereRatio, smallest / sigma_t, std::min(room, kLargestSphere / sigma_t)};
}

}  // namespace stf::render
