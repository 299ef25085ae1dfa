// Float or double for the brute-force tracer: the collision loop of render/ladder.cpp (CollisionWalk)
// (exponential flight, leaving test, albedo, Henyey-Greenstein turn about a branchless frame)
// in both precisions, from the centre of a sphere until the path leaves or roulette ends it,
// one thread; and the renderer itself (double, no shadow rays) rendering the one-sphere scene. Both precisions turn with the
// tracer's double sincos polynomial. Prints collisions per second
// as JSON, with the float / double ratio measured in the same run.
//   collision_bench [PATHS]
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include <stf/math.h>

#include "stf/hg.h"
#include "stf/render/pixel_rng.h"
#include "stf/render/render.h"
#include "stf/render/scene_geometry.h"
#include "stf/render/sphere_scene.h"

namespace {

template <typename Real>
struct V3 {
  Real x, y, z;
};

template <typename Real>
V3<Real> turn(const V3<Real>& w, Real c, Real s, double u) {
  const Real sign = std::copysign(Real(1), w.z), a = -1 / (sign + w.z), b = w.x * w.y * a;
  const V3<Real> t1{1 + sign * w.x * w.x * a, sign * b, -sign * w.x}, t2{b, sign + w.y * w.y * a, -w.y};
  double sp, cp;
  stf::sincos_2pi(u, sp, cp);  // the tracer's polynomial, in both: std::sin and std::cos cost more than all else
  const Real ct1 = s * Real(cp), ct2 = s * Real(sp);
  return {c * w.x + ct1 * t1.x + ct2 * t2.x, c * w.y + ct1 * t1.y + ct2 * t2.y, c * w.z + ct1 * t1.z + ct2 * t2.z};
}

// Collisions per second of `paths` walks in a sphere of optical radius tau.
template <typename Real>
double collisions_per_second(long paths, Real tau, Real albedo, Real g, long& collisions) {
  const stf::HgParams<Real> hg = stf::HgParams<Real>::make(g);
  const Real r2 = tau * tau;
  collisions = 0;
  const auto start = std::chrono::steady_clock::now();
  for (long p = 0; p < paths; ++p) {
    stf::render::PixelRng rng(1, std::uint64_t(p));
    V3<Real> x{0, 0, 0}, w{0, 0, 1};
    Real throughput = 1;
    for (;;) {
      const Real t = -std::log(Real(rng.uniform_open0()));
      x = {x.x + t * w.x, x.y + t * w.y, x.z + t * w.z};
      if (x.x * x.x + x.y * x.y + x.z * x.z > r2) break;
      ++collisions;
      throughput *= albedo;
      const stf::CosSin<Real> cs = stf::sample_hg(hg, Real(rng.uniform()));
      w = turn(w, cs.cos_theta, cs.sin_theta, rng.uniform());
      if (throughput < Real(0.25)) {
        if (Real(rng.uniform()) * Real(0.25) >= throughput) break;
        throughput = Real(0.25);
      }
    }
  }
  return double(collisions) / std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

int main(int argc, char** argv) {
  const long paths = argc > 1 ? std::atol(argv[1]) : 20000;
  long nd = 0, nf = 0;
  const double d = collisions_per_second<double>(paths, 30.0, 0.999, 0.8, nd);
  const double f = collisions_per_second<float>(paths, 30.0f, 0.999f, 0.8f, nf);
  // The tracer itself: its scene at tau 100, one thread.
  stf::Medium m;
  m.sigma_s = 99.9, m.sigma_a = 0.1, m.g = 0.8, m.radius = 1;
  stf::render::ImageSettings s;
  s.width = s.height = 32, s.spp = 64, s.run.threads = 1;
  const stf::scene::RenderScene scene = stf::render::sphere_scene(m, s.width, s.height);
  const stf::render::SceneGeometry geometry(scene, stf::render::FreeRadius::kQuery);
  stf::render::PathOptions options;
  options.next_event = false;  // collisions alone
  const stf::render::Image image =
      stf::render::render(scene, stf::render::ScenePaths(scene, geometry, nullptr, options), s, stf::render::Channels::kOne);
  std::printf("{\"double_collisions_per_s\": %.4g, \"float_collisions_per_s\": %.4g, \"float_over_double\": %.3f, "
              "\"tracer_collisions_per_s\": %.4g, \"collisions_double\": %ld, \"collisions_float\": %ld}\n",
              d, f, f / d, double(image.collisions) / image.seconds, nd, nf);
  return 0;
}
