// The path tracer of render/ against exact results: a purely absorbing sphere (its image is
// the transmittance along each camera ray) and the identities that make the two methods
// comparable (the same image for any thread count; strides never taken where no sphere fits).
#include <gtest/gtest.h>

#include <cmath>

#include "stf/scene/plan.h"
#include "stf/render/ladder.h"
#include "stf/render/render.h"
#include "stf/render/scene_geometry.h"
#include "stf/render/sphere_scene.h"
#include "stf/scene/scene.h"

namespace stf::render {
namespace {

// The one-sphere form of stf render, as it renders: its scene, geometry and paths (brute force
// without `pack`).
struct SphereRender {
  SphereRender(const Medium& m, int width, int height, const std::vector<PackEntry>* pack = nullptr)
      : scene(sphere_scene(m, width, height)), geometry(scene, FreeRadius::kQuery), paths(scene, geometry, pack) {}
  Image render(ImageSettings s) const { return stf::render::render(scene, paths, s, Channels::kOne); }
  scene::RenderScene scene;
  SceneGeometry geometry;
  ScenePaths paths;
};

// exp(-sigma_t * chord) averaged over the pixel's area (a sub-pixel midpoint grid): what a
// pixel of a pure absorber converges to. Camera rays head away from the sun, so the sky behind
// is 1 everywhere.
double pixel_transmittance(const Medium& m, const scene::CameraSpec& camera, int px, int py, int width, int height) {
  const int sub = 64;
  double sum = 0;
  for (int i = 0; i < sub; ++i)
    for (int j = 0; j < sub; ++j) {
      const Ray ray = camera_ray(camera, px + (i + 0.5) / sub, py + (j + 0.5) / sub, width, height);
      const double b = dot(ray.origin, ray.direction), c = dot(ray.origin, ray.origin) - m.radius * m.radius;
      const double chord = b * b > c && b < 0 ? 2 * std::sqrt(b * b - c) : 0;
      sum += std::exp(-m.sigma_t() * chord) * kSphereSky;
    }
  return sum / (sub * sub);
}

TEST(Render, PureAbsorberGivesTheTransmittance) {
  Medium m;
  m.sigma_s = 0, m.sigma_a = 1.5, m.g = 0, m.radius = 1;
  ImageSettings s;
  s.width = s.height = 12;
  s.spp = 4000;
  s.seed = 7;
  const SphereRender sphere(m, s.width, s.height);
  const Image image = sphere.render(s);
  // Each sample is 0 or 1 (absorbed or through): z-scores on the estimator's own variance.
  // Where every sample went through, the pixel (sky, or a sliver of the sphere's rim) absorbs
  // with a probability of a few per spp at most.
  double z2 = 0;
  int counted = 0;
  for (int py = 0; py < s.height; ++py)
    for (int px = 0; px < s.width; ++px) {
      const std::size_t i = std::size_t(py * s.width + px);
      const double exact = pixel_transmittance(m, sphere.scene.camera, px, py, s.width, s.height);
      const double sd = std::sqrt(image.variance_of_mean[i]);
      if (sd == 0) {
        EXPECT_NEAR(image.mean[i], exact, 5.0 / double(s.spp)) << "pixel " << px << ", " << py;
        continue;
      }
      const double z = (image.mean[i] - exact) / sd;
      EXPECT_LT(std::abs(z), 5) << "pixel " << px << ", " << py << ": " << image.mean[i] << " vs " << exact;
      z2 += z * z, ++counted;
    }
  ASSERT_GT(counted, 50);
  // The mean squared z-score of n pixels is 1 +- sqrt(2 / n).
  EXPECT_NEAR(z2 / counted, 1, 5 * std::sqrt(2.0 / counted));
}

TEST(Render, SameImageForAnyThreadCount) {
  Medium m;
  m.sigma_s = 9, m.sigma_a = 0.2, m.g = 0.7, m.radius = 1;
  ImageSettings s;
  s.width = 20, s.height = 14;
  s.spp = 8;
  const SphereRender sphere(m, s.width, s.height);
  s.run.threads = 1;
  const Image one = sphere.render(s);
  s.run.threads = 3;
  const Image three = sphere.render(s);
  EXPECT_EQ(one.mean, three.mean);
  EXPECT_EQ(one.variance_of_mean, three.variance_of_mean);
  EXPECT_EQ(one.collisions, three.collisions);
}

// Without a sphere that fits, the strided method takes exactly the brute-force steps.
TEST(Render, StridesWithoutSpheresAreBruteForce) {
  Medium m;
  m.sigma_s = 1.2, m.sigma_a = 0.3, m.g = 0.5, m.radius = 1;
  ImageSettings s;
  s.width = s.height = 16;
  s.spp = 16;
  const std::vector<PackEntry> none;
  const Image a = SphereRender(m, s.width, s.height).render(s), b = SphereRender(m, s.width, s.height, &none).render(s);
  EXPECT_EQ(a.mean, b.mean);
  EXPECT_EQ(a.collisions, b.collisions);
  EXPECT_EQ(b.strides, 0);
}

TEST(Render, CancelStopsEarly) {
  Medium m;
  m.sigma_s = 50, m.sigma_a = 0.01, m.g = 0.9, m.radius = 1;
  ImageSettings s;
  s.spp = 1000000;
  std::atomic<bool> cancel{false};
  int calls = 0;
  s.run.cancel = &cancel;
  s.run.progress = [&](std::string_view, std::int64_t, std::int64_t) { ++calls, cancel = true; };
  const Image image = SphereRender(m, s.width, s.height).render(s);
  EXPECT_TRUE(cancel.load());
  EXPECT_LT(image.paths, std::int64_t(s.width) * s.height * s.spp);
}

// A path that barely turns (g -> 1) crosses a sphere of optical radius tau on a straight
// chord of length tau: its collisions are Poisson with mean tau. The walk of
// crossing_collisions against that limit (4.5 standard errors of 20000 paths), more turning
// (smaller g) keeping the path longer inside, and the ladder's break-even against it.
TEST(Render, CrossingCollisionsHaveTheStraightPathLimit) {
  for (double tau : {0.5, 2.0, 8.0}) EXPECT_NEAR(crossing_collisions(tau, 0.99999), tau, 4.5 * std::sqrt(tau / 20000)) << tau;
  for (double tau : {2.0, 8.0}) {
    EXPECT_GT(crossing_collisions(tau, 0.5), crossing_collisions(tau, 0.99999) + 0.1) << tau;
    EXPECT_GT(crossing_collisions(tau, 0.0), crossing_collisions(tau, 0.5)) << tau;
  }
  // Straight paths: tau 4 takes 4 collisions, tau 8 takes 8; 1 - e^{-1} of tau-1 paths collide.
  EXPECT_EQ(smallest_paying_tau(0.99999, 4.5), 8);
  EXPECT_EQ(smallest_paying_tau(0.99999, 3.5), 4);
  EXPECT_EQ(smallest_paying_tau(0.99999, 0.5), 1);
  EXPECT_EQ(smallest_paying_tau(0.99999, 1e9), 16);
}

// The spheres a scene planned from the ladder holds (stf render plans its pack so).
std::vector<double> planned_taus(const Medium& m) {
  const PackLadder ladder = pack_ladder(m);
  scene::Scene sc;
  sc.settings.tau_skip = ladder.smallest, sc.settings.tau_ratio = ladder.ratio;
  sc.media.push_back({"m", m.sigma_s, m.sigma_a, m.g, ladder.radius_min, ladder.radius_max, 0});
  std::vector<double> taus;
  for (const scene::PlanEntry& e : scene::make_plan(sc, ::testing::TempDir() + "/stf_no_cache").entries)
    if (e.action != "skip") taus.push_back(e.tau);
  return taus;
}

// stf render's pack: from the sphere that pays at the stride cost, by 2, up to the medium's tau
// or tau 128, whichever is smaller (the larger ones cost most of the precompute for about 1% of
// the strides); a medium thinner than the smallest sphere gets none.
TEST(Render, PackLadderStopsAtTau128) {
  Medium cloud;
  cloud.sigma_s = 99.99, cloud.sigma_a = 0.01, cloud.g = 0.85, cloud.radius = 10;
  EXPECT_EQ(planned_taus(cloud), (std::vector<double>{4, 8, 16, 32, 64, 128}));
  cloud.radius = 0.2;  // tau 20
  EXPECT_EQ(planned_taus(cloud), (std::vector<double>{4, 8, 16}));
  cloud.radius = 0.03;  // tau 3
  EXPECT_TRUE(planned_taus(cloud).empty());
}

}  // namespace
}  // namespace stf::render
