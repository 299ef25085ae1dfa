#include "tracer.h"

#include <cmath>

#include <stf/lookup.h>
#include <stf/math.h>
#include <stf/vmf.h>

namespace stf::render {

namespace {

const std::string kMediumName = "render";

bool close(double a, double b) { return std::abs(a - b) <= 1e-9 * std::max(1.0, std::abs(b)); }

// w' at polar cosine `c` (sine `s`) and azimuth 2 pi u about w.
Vec3 turn(const Vec3& w, double c, double s, double u) {
  Vec3 t1, t2;
  orthonormal_basis(w, t1, t2);
  double sp, cp;
  sincos_2pi(u, sp, cp);
  const double ct1 = s * cp, ct2 = s * sp;
  return {c * w.x + ct1 * t1.x + ct2 * t2.x, c * w.y + ct1 * t1.y + ct2 * t2.y, c * w.z + ct1 * t1.z + ct2 * t2.z};
}

}  // namespace

CollisionWalk::CollisionWalk(const Medium& m)
    : inv_sigma_t_(1 / m.sigma_t()), albedo_(m.albedo()), radius2_(m.radius * m.radius),
      hg_(HgParams<double>::make(m.g)) {}

bool CollisionWalk::leaves_after_flight(Vec3& x, Vec3& w, double& throughput, PixelRng& rng) const {
  const double t = -std::log(rng.uniform_open0()) * inv_sigma_t_;
  x = {x.x + t * w.x, x.y + t * w.y, x.z + t * w.z};
  if (dot(x, x) > radius2_) return true;  // the sphere is convex: past the boundary means out
  throughput *= albedo_;
  const CosSin<double> cs = sample_hg(hg_, rng.uniform());
  w = turn(w, cs.cos_theta, cs.sin_theta, rng.uniform());
  return false;
}

bool survives_roulette(double& throughput, PixelRng& rng) {
  if (throughput >= kRouletteBelow) return true;
  if (rng.uniform() * kRouletteBelow >= throughput) return false;
  throughput = kRouletteBelow;
  return true;
}

double BruteForce::radiance(const Vec3& entry, const Vec3& direction, PixelRng& rng, PathCounters& counters) const {
  Vec3 x = entry, w = direction;
  double throughput = 1;
  for (;;) {
    if (walk_.leaves_after_flight(x, w, throughput, rng)) return throughput * sky_radiance(w);
    ++counters.collisions;
    if (!survives_roulette(throughput, rng)) return 0;
  }
}

std::vector<PackEntry> entries_for(const Medium& m, const std::vector<PackEntry>& pack) {
  std::vector<PackEntry> mine;
  for (const PackEntry& e : pack)
    if (close(e.model.albedo, m.albedo()) && close(e.model.g, m.g)) mine.push_back({kMediumName, e.model});
  return mine;
}

ShellStrides::ShellStrides(const Medium& m, const std::vector<PackEntry>& pack)
    : medium_(m), walk_(m), spheres_(entries_for(m, pack), kMediumName) {}

double ShellStrides::radiance(const Vec3& entry, const Vec3& direction, PixelRng& rng, PathCounters& counters) const {
  const double sigma_t = medium_.sigma_t();
  Vec3 x = entry, w = direction;
  double throughput = 1;
  for (;;) {
    // The largest precomputed sphere around x inside the medium: a path starting at its
    // centre in flight is exactly what the sphere's model describes (free paths are
    // memoryless), so the path jumps to the sphere's exit.
    double r = 0;
    const int sphere = spheres_.find(sigma_t, medium_.radius - length(x), r);
    if (sphere >= 0) {
      const ShellSampler& s = spheres_.sampler(sphere);
      const double u0 = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform(), u3 = rng.uniform();
      const WorldExit exit = s.jump(x, w, r, u0, u1, u2, u3);
      x = exit.point, w = exit.direction;
      throughput *= s.escape_probability();
      ++counters.strides;
    } else {
      if (walk_.leaves_after_flight(x, w, throughput, rng)) return throughput * sky_radiance(w);
      ++counters.collisions;
    }
    if (!survives_roulette(throughput, rng)) return 0;
  }
}

}  // namespace stf::render
