// The renderer's threads and memory under the sanitizers: the same sources built twice
// (tests/CMakeLists.txt, "sanitize"), once under ThreadSanitizer and once under AddressSanitizer
// and UndefinedBehaviorSanitizer, with NDEBUG undefined so that SceneGeometry::trace checks
// every ray it hands to Embree. Each test renders a few pixels on four threads through
// ScenePaths, by brute force and in strides:
//  - the shipped render scenes (data/scenes/), their media thinned so that brute force ends;
//  - the strided test scene (tests/support/strided_scene.h) through the test pack, under a sun
//    and under an environment map, both methods, each image the same to the bit on one thread;
//  - a ray that meets the ground plane beyond where Embree can trace from.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cfloat>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <stf/pack.h>

#include "stf/render/render.h"
#include "stf/render/scene_geometry.h"
#include "stf/render/scene_paths.h"
#include "stf/scene/render_scene.h"
#include "strided_scene.h"

namespace {

using namespace stf;
namespace fs = std::filesystem;

constexpr int kThreads = 4;

// The largest optical radius of an object's medium a test renders by brute force: a path then
// ends after some hundreds of collisions (albedo 0.9999 lets it run to thousands).
constexpr double kThinTau = 4;

class RenderSanitize : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("stf-sanitize-" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& bytes) const {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    return path;
  }
  fs::path dir_;
};

render::Image draw(const scene::RenderScene& sc, const render::ScenePaths& paths, int size, int spp, int threads) {
  render::ImageSettings s;
  s.width = s.height = size, s.spp = spp, s.seed = 3, s.run.threads = threads;
  return render::render(sc, paths, s);
}

void expect_finite(const render::Image& image, const std::string& what) {
  for (std::size_t i = 0; i < image.mean.size(); ++i) {
    ASSERT_TRUE(std::isfinite(image.mean[i])) << what << " value " << i;
    ASSERT_TRUE(std::isfinite(image.variance_of_mean[i])) << what << " value " << i;
  }
}

// The same image on one thread and on kThreads: every pixel has its own random stream, so any
// difference is a race or a read of memory not written.
void expect_same(const render::Image& a, const render::Image& b, const std::string& what) {
  EXPECT_EQ(a.mean, b.mean) << what;
  EXPECT_EQ(a.variance_of_mean, b.variance_of_mean) << what;
  EXPECT_EQ(a.collisions, b.collisions) << what;
  EXPECT_EQ(a.strides, b.strides) << what;
  EXPECT_EQ(a.rays, b.rays) << what;
}

std::vector<PackEntry> test_pack() {
  std::vector<PackEntry> pack;
  std::string error;
  EXPECT_TRUE(read_pack_file(STF_RENDER_PACK, pack, error)) << error;
  return pack;
}

// A latitude-longitude map in PFM (bottom row first), brighter on one side.
std::string sky_map(int width, int height) {
  std::string bytes = "PF\n" + std::to_string(width) + " " + std::to_string(height) + "\n-1.0\n";
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u)
      for (int c = 0; c < 3; ++c) {
        const float x = 0.2f + 0.1f * float(c) + (u == width / 3 && v == height / 2 ? 40.0f : 0.0f);
        bytes.append(reinterpret_cast<const char*>(&x), sizeof x);
      }
  return bytes;
}

const std::string kCamera = "[camera]\nposition = [0, 0.4, 2.2]\nlook_at = [0, 0, 0]\nfov = 35\n";

// Each shipped render scene by brute force, its media thinned to an optical radius of kThinTau
// (the geometry, glass, ground and lights as shipped), on kThreads threads and on one.
TEST_F(RenderSanitize, ShippedScenesByBruteForce) {
  for (const char* name : {"milk_spot", "dense_spot", "lit_torus"}) {
    scene::RenderScene sc = scene::read_render_scene(std::string(STF_SOURCE_DIR) + "/data/scenes/" + name + ".toml");
    const render::SceneGeometry geometry(sc, render::FreeRadius::kGrid, 48, RunContext{kThreads, nullptr, {}});
    for (std::size_t i = 0; i < sc.objects.size(); ++i) {
      scene::MediumSpec& m = sc.media[std::size_t(sc.objects[i].medium)];
      for (std::size_t c = 0; c < 3; ++c) {
        const double tau = m.sigma_t(int(c)) * geometry.largest_free_radius(int(i));
        if (tau > kThinTau) m.sigma_s[c] *= kThinTau / tau, m.sigma_a[c] *= kThinTau / tau;
      }
    }
    const render::ScenePaths paths(sc, geometry);
    const render::Image many = draw(sc, paths, 8, 3, kThreads), one = draw(sc, paths, 8, 3, 1);
    EXPECT_GT(many.collisions, 0) << name;
    expect_finite(many, name);
    expect_same(many, one, name);
  }
}

// The strided test scene under a sun and under an environment map, by brute force and in
// strides through the test pack, with its free radii from the grid and from Embree's queries.
TEST_F(RenderSanitize, StridedSceneBothMethods) {
  write("sky.pfm", sky_map(16, 8));
  const std::string sun = "[light]\nsky = 0.2\nsun_direction = [1, 1.5, 0.5]\nsun_radiance = [6, 5, 4]\nsun_angle = 25\n";
  const std::string map = "[light]\nenvironment = \"sky.pfm\"\nsun_radiance = 3\n";
  const std::vector<PackEntry> pack = test_pack();
  ASSERT_FALSE(pack.empty());
  for (const std::string& light : {sun, map})
    for (const render::FreeRadius free : {render::FreeRadius::kGrid, render::FreeRadius::kQuery}) {
      const scene::RenderScene sc = scene::read_render_scene(write("scene.toml", kCamera + light + test::strided_objects()));
      const render::SceneGeometry geometry(sc, free, 32, RunContext{kThreads, nullptr, {}});
      const render::ScenePaths brute(sc, geometry), strided(sc, geometry, &pack);
      const std::string what = (light == sun ? "sun, " : "map, ") + std::string(free == render::FreeRadius::kGrid ? "grid" : "query");
      const render::Image b = draw(sc, brute, 8, 6, kThreads), s = draw(sc, strided, 8, 6, kThreads);
      EXPECT_GT(b.collisions, 0) << what;
      EXPECT_GT(s.strides, 0) << what;
      EXPECT_GT(s.shadow_rays, 0) << what;
      expect_finite(b, "brute, " + what);
      expect_finite(s, "strides, " + what);
      expect_same(b, draw(sc, brute, 8, 6, 1), "brute, " + what);
      expect_same(s, draw(sc, strided, 8, 6, 1), "strides, " + what);
    }
}

// A ray that skims the ground plane meets it far beyond the scene: no hit there may put the
// next ray's origin where Embree cannot hold it in float (beyond about 1.8e18, where its
// ray.valid() fails), so such a ray sees the horizon instead.
TEST_F(RenderSanitize, RaysSkimmingTheGroundStayTraceable) {
  const scene::RenderScene sc = scene::read_render_scene(write("scene.toml", kCamera + "[light]\nsky = 1\n" + test::strided_objects()));
  const render::SceneGeometry geometry(sc, render::FreeRadius::kGrid, 16);
  const Vec3 origin{3, 2, 0};
  for (const double dy : {-1e-3, -1e-12, -1e-17, -1e-19, -1e-30, -1e-300}) {
    const Vec3 d = normalize({1, dy, 0.25});
    const render::SurfaceHit h = geometry.trace(origin, d);
    if (!h.found) continue;
    const Vec3 x = origin + h.t * d;
    EXPECT_LT(std::max({std::abs(x.x), std::abs(x.y), std::abs(x.z)}), 1e18) << dy;
    geometry.trace(geometry.spawn(x, h.normal, {1, 1, 0}), normalize({-1, 1, 0}));  // from the hit: a traceable ray
  }
}

}  // namespace
