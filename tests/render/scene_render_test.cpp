// Render scenes (stf/render/scene_paths.h): exact limits and estimators against each other.
//  - A white furnace (sky 1, no sun, media that never absorb) is exactly 1 in every pixel, through
//    index-matched and dielectric boundaries, meshes and analytic spheres: no path leaks or
//    gains energy at a boundary.
//  - Next-event estimation with MIS and the sun found only by escaping paths draw the same image.
//  - An analytic sphere and an icosphere of the same radius draw the same image, within the noise
//    and the tessellation's own difference.
//  - Scenes that cannot be rendered are refused in one line naming the file and the key.
#include <gtest/gtest.h>

#include <fstream>

#include "image_compare.h"
#include "path_state.h"
#include "scene_fixture.h"
#include "strided_scene.h"
#include "stf/render/image_file.h"
#include "stf/scene/scene_error.h"

namespace {

using namespace stf;
namespace fs = std::filesystem;

using test::kCamera;
using test::kMeshes;
using SceneRender = test::SceneFixture;

TEST_F(SceneRender, WhiteFurnaceIsExactlyOne) {
  const std::string scene = kCamera + R"(
[light]
sky = 1
sun_radiance = 0
[[media]]
name = "white"
sigma_s = [20, 8, 40]
sigma_a = 0
g = [0.0, 0.5, 0.9]
[[objects]]
mesh = ")" + kMeshes + R"(torus.obj"
translate = [-0.45, 0, 0]
scale = 0.9
medium = "white"
[[objects]]
shape = "sphere"
radius = 0.3
translate = [0.5, 0, 0]
medium = "white"
ior = 1.5
)";
  const render::Image image = draw(scene, 6, 3);
  EXPECT_GT(image.collisions, 1000);
  for (std::size_t i = 0; i < image.mean.size(); ++i) {
    ASSERT_NEAR(image.mean[i], 1, 1e-12) << i;
    ASSERT_NEAR(image.variance_of_mean[i], 0, 1e-20) << i;
  }
}

const std::string kLitScene =
    test::lit_box_scene("sky = [0.4, 0.5, 0.6]\nsun_direction = [1, 2, 0.5]\nsun_radiance = [60, 50, 40]\nsun_angle = 4");

TEST_F(SceneRender, NextEventEstimationDrawsTheImageOfEscapingPaths) {
  const render::Image with = draw(kLitScene, 300, 5, true), without = draw(kLitScene, 1200, 6, false);
  EXPECT_GT(with.shadow_rays, 0);
  EXPECT_EQ(without.shadow_rays, 0);
  // Every camera path casts its first ray from outside, and every shadow ray at least one leg.
  EXPECT_GE(with.rays, with.paths + with.shadow_rays);
  EXPECT_GE(without.rays, without.paths);
  const ImageComparison r =
      compare_images(without.mean, without.variance_of_mean, with.mean, with.variance_of_mean, 24, 24, 3, 4);
  EXPECT_GT(r.blocks, 80);
  EXPECT_LT(r.max_block_z, 4.5);
  for (int c = 0; c < 3; ++c) EXPECT_LT(std::abs(r.mean_z[std::size_t(c)]), 4.5) << c;
}

// A lit, index-matched medium the test pack's spheres stride through, under a large sun that
// paths leaving strides meet often.
const std::string kStridedScene = kCamera + R"(
[light]
sky = 0.02
sun_direction = [1, 1.5, 0.5]
sun_radiance = [6, 5, 4]
sun_angle = 25
)" + test::strided_objects();

std::vector<PackEntry> test_pack(const char* path) {
  std::vector<PackEntry> pack;
  std::string error;
  EXPECT_TRUE(read_pack_file(path, pack, error)) << error;
  return pack;
}

// Strides keep their light: shadow rays at a stride's exit, weighed by the exit's direction
// density and combined with the direction drawn there by the power heuristic, draw the image
// of paths that find the lights by leaving alone, for hemispherical and lifted models; taken at
// weight 1 after a shadow ray (the MIS weight at exits removed), the light is counted twice
// and the image is brighter by far more than its noise.
TEST_F(SceneRender, NextEventEstimationAtStrideExitsDrawsTheImageOfEscapingPaths) {
  for (const char* file : {STF_RENDER_PACK, STF_RENDER_PACK_LIFTED}) {
    const std::vector<PackEntry> pack = test_pack(file);
    const render::Image with = draw_with(kStridedScene, &pack, {true, false, true}, 600, 5);
    const render::Image without = draw_with(kStridedScene, &pack, {false, false, true}, 1200, 6);
    EXPECT_GT(with.strides, with.paths / 4) << file;
    EXPECT_GT(with.shadow_rays, 0);
    const ImageComparison r =
        compare_images(without.mean, without.variance_of_mean, with.mean, with.variance_of_mean, 24, 24, 3, 4);
    EXPECT_GT(r.blocks, 80);
    EXPECT_LT(r.max_block_z, 4.5) << file;
    for (int c = 0; c < 3; ++c) EXPECT_LT(std::abs(r.mean_z[std::size_t(c)]), 4.5) << file << " channel " << c;
    const render::Image twice = draw_with(kStridedScene, &pack, {true, false, false}, 600, 7);
    const ImageComparison d = compare_images(with.mean, with.variance_of_mean, twice.mean, twice.variance_of_mean, 24, 24, 3, 4);
    EXPECT_GT(std::max({d.mean_z[0], d.mean_z[1], d.mean_z[2]}), 5) << file;
  }
}

// The same under an environment map alone (a dim sky with a bright patch low on one side): the
// map's shadow rays at exits, weighed against the exit's density, and paths that find the map
// by leaving, weighed the other way.
TEST_F(SceneRender, NextEventEstimationAtStrideExitsWithAMapDrawsTheImageOfEscapingPaths) {
  const std::vector<double> rgb = test::patch_sky(1.0 / 3, 20);
  render::write_exr(path("patch.exr"), {rgb, 32, 16, 3});
  std::string scene = kStridedScene;
  const std::size_t light = scene.find("[light]"), media = scene.find("[[media]]");
  scene.replace(light, media - light, "[light]\nenvironment = \"patch.exr\"\nsun_radiance = 0\n");
  const std::vector<PackEntry> pack = test_pack(STF_RENDER_PACK);
  const render::Image with = draw_with(scene, &pack, {true, false, true}, 600, 8);
  const render::Image without = draw_with(scene, &pack, {false, false, true}, 1200, 9);
  EXPECT_GT(with.rays_by[render::kShadowExit], 0);
  const ImageComparison r =
      compare_images(without.mean, without.variance_of_mean, with.mean, with.variance_of_mean, 24, 24, 3, 4);
  EXPECT_GT(r.blocks, 80);
  EXPECT_LT(r.max_block_z, 4.5);
  for (int c = 0; c < 3; ++c) EXPECT_LT(std::abs(r.mean_z[std::size_t(c)]), 4.5) << c;
}

TEST_F(SceneRender, AnalyticSphereAndIcosphereAgree) {
  auto scene = [&](const std::string& object) {
    return kCamera + R"(
[light]
sky = 0.5
sun_direction = [0.5, 1, 1]
sun_radiance = 30
[[media]]
name = "m"
sigma_s = [10, 6, 3]
sigma_a = 0.05
g = 0.7
[[objects]]
)" + object + "\nmedium = \"m\"\n";
  };
  const render::Image sphere = draw(scene("shape = \"sphere\"\nradius = 0.5"), 400, 7);
  const render::Image mesh = draw(scene("mesh = \"" + kMeshes + "icosphere.obj\""), 400, 8);
  const ImageComparison r =
      compare_images(sphere.mean, sphere.variance_of_mean, mesh.mean, mesh.variance_of_mean, 24, 24, 3, 4);
  EXPECT_LT(r.max_block_z, 4.5);
  // The icosphere (5120 triangles) lies inside the sphere, its faces' planes within 0.12% of
  // the radius: a difference far below this image's noise and the 1% asked of the means.
  for (int c = 0; c < 3; ++c) {
    EXPECT_LT(std::abs(r.mean_z[std::size_t(c)]), 4.5) << c;
    EXPECT_NEAR(r.mean_ratio[std::size_t(c)], 1, 0.01) << c;
  }
}

// Inside an analytic sphere paths take their own steps (no free radius, no flight rays: its
// surface is the only one inside it); in strides with shadow rays at collisions and exits they
// draw the image the general loop draws through the icosphere of that radius. Without the ground
// the sphere is alone: a path leaving it takes the sky and the sun (with its MIS weight) at once,
// casting no ray after it.
TEST_F(SceneRender, AnalyticSphereStridesAgreeWithTheIcosphere) {
  const std::vector<PackEntry> pack = test_pack(STF_RENDER_PACK);
  std::string sphere = kStridedScene;
  const std::string mesh_line = sphere.substr(sphere.find("mesh = "), sphere.find('\n', sphere.find("mesh = ")) - sphere.find("mesh = "));
  sphere.replace(sphere.find(mesh_line), mesh_line.size(), "shape = \"sphere\"\nradius = 0.5");
  // Ideal strides through the sphere's own steps: the true transport, brute force's image.
  const render::Image ideal = draw_with(sphere, &pack, {true, true}, 300, 13), brute = draw(sphere, 300, 14);
  EXPECT_GT(ideal.ideal_collisions, ideal.paths);
  const ImageComparison e = compare_images(brute.mean, brute.variance_of_mean, ideal.mean, ideal.variance_of_mean, 24, 24, 3, 4);
  EXPECT_LT(e.max_block_z, 4.5);
  for (int c = 0; c < 3; ++c) EXPECT_LT(std::abs(e.mean_z[std::size_t(c)]), 4.5) << c;
  const auto without_ground = [](std::string scene) { return scene.substr(0, scene.find("[ground]")); };
  for (const bool alone : {false, true}) {
    const std::string a = alone ? without_ground(sphere) : sphere, m = alone ? without_ground(kStridedScene) : kStridedScene;
    const render::Image analytic = draw_with(a, &pack, {}, 600, 11), mesh = draw_with(m, &pack, {}, 600, 12);
    EXPECT_GT(analytic.strides, analytic.paths / 4) << alone;
    EXPECT_GT(analytic.rays_by[render::kShadowExit], 0) << alone;
    EXPECT_GT(analytic.rays_by[render::kShadowCollision], 0) << alone;
    EXPECT_EQ(analytic.rays_by[render::kOutsideRay] == 0, alone);  // alone: no ray after leaving
    const ImageComparison r =
        compare_images(analytic.mean, analytic.variance_of_mean, mesh.mean, mesh.variance_of_mean, 24, 24, 3, 4);
    EXPECT_GT(r.blocks, 80) << alone;
    EXPECT_LT(r.max_block_z, 4.5) << alone;
    for (int c = 0; c < 3; ++c) {
      EXPECT_LT(std::abs(r.mean_z[std::size_t(c)]), 4.5) << alone << " " << c;
      EXPECT_NEAR(r.mean_ratio[std::size_t(c)], 1, 0.01) << alone << " " << c;
    }
  }
}

// The shadow rays' first test without an exponential (may_pass) turns a vertex away only where
// may_cast(u, exp(-d)) would (but for u = 0 past depth 700, where exp(-d) is below 1e-304), and it
// turns away most of what that would.
TEST(ShadowOdds, MayPassTurnsAwayOnlyWhatTheExponentialWould) {
  render::PixelRng rng(9, 0);
  int refused = 0, turned = 0;
  for (int i = 0; i < 200000; ++i) {
    const double d = 800 * rng.uniform() * rng.uniform();
    const double u = i % 1000 == 0 ? 0.0 : rng.uniform() * (rng.uniform() < 0.5 ? 1.0 : 1e-6);
    const bool passes = render::may_cast(u, std::exp(-d));
    if (!render::may_pass(u, d)) {
      ASSERT_TRUE(!passes || (u == 0 && d >= 700)) << "u " << u << ", depth " << d;
    }
    refused += !passes, turned += !passes && !render::may_pass(u, d);
  }
  EXPECT_GT(turned, 0.9 * refused) << refused;
}

// A pack with no sphere of the scene's media leaves the strided paths brute force's, draw for
// draw: the same image to the bit.
TEST_F(SceneRender, StridesWithoutSpheresAreBruteForceBitForBit) {
  const scene::RenderScene sc = scene::read_render_scene(write("scene.toml", kLitScene));
  const render::SceneGeometry geometry(sc, render::FreeRadius::kGrid, 64);
  const std::vector<PackEntry> none;
  const render::ScenePaths brute(sc, geometry), strided(sc, geometry, &none);
  render::ImageSettings s;
  s.width = s.height = 12, s.spp = 30, s.run.threads = 3;
  const render::Image a = render::render(sc, brute, s), b = render::render(sc, strided, s);
  EXPECT_GT(a.collisions, 1000);
  EXPECT_EQ(a.mean, b.mean);
  EXPECT_EQ(a.variance_of_mean, b.variance_of_mean);
  EXPECT_EQ(a.collisions, b.collisions);
}

// Each bad scene: the message names the file and the key, and holds the word that says why.
// A scene without a [light] table gets the default sun as a unit direction, as one that names
// it does (an unnormalised default once made its brute-force images 21x too bright).
TEST_F(SceneRender, TheDefaultSunIsAUnitDirection) {
  const std::string scene = "[[media]]\nname = \"m\"\npreset = \"milk\"\n[[objects]]\nshape = \"sphere\"\nmedium = \"m\"\n";
  const scene::RenderScene bare = scene::read_render_scene(write("bare.toml", scene));
  const scene::RenderScene named =
      scene::read_render_scene(write("named.toml", scene + "[light]\nsun_direction = [1, 1, -1]\n"));
  EXPECT_NEAR(length(bare.light.sun_direction), 1, 1e-15);
  EXPECT_DOUBLE_EQ(bare.light.sun_direction.x, named.light.sun_direction.x);
  EXPECT_DOUBLE_EQ(bare.light.sun_direction.z, named.light.sun_direction.z);
}

TEST_F(SceneRender, BadScenesAreRefusedNamingFileAndKey) {
  std::ofstream(dir_ / "open.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\n";
  const std::string medium = "[[media]]\nname = \"m\"\nsigma_s = 1\nsigma_a = 0.1\ng = 0.5\n";
  const std::string object = "[[objects]]\nshape = \"sphere\"\nmedium = \"m\"\n";
  const std::vector<std::tuple<std::string, std::string, std::string>> cases = {
      {medium + object + "[camera]\nzoom = 2\n", "camera.zoom", "unknown key"},
      {medium + "[[objects]]\nmesh = \"missing.obj\"\nmedium = \"m\"\n", "objects[0].mesh", "no such file"},
      {medium + "[[objects]]\nmesh = \"open.obj\"\nmedium = \"m\"\n", "open.obj", "not closed"},
      {medium + object + "ior = 0.8\n", "objects[0].ior", "[1, 4]"},
      {"[[media]]\nname = \"m\"\nsigma_s = -1\nsigma_a = 0.1\ng = 0.5\n" + object, "media[0].sigma_s", "[0,"},
      {"[[media]]\nname = \"m\"\npreset = \"gravy\"\n" + object, "media[0].preset", "unknown medium 'gravy'"},
      {medium + "[[objects]]\nshape = \"sphere\"\nmedium = \"milk\"\n", "objects[0].medium", "no [[media]] named"},
      {medium + object + object, "objects[1]", "overlap"},
      {medium + object + "[ground]\nheight = 0\n", "objects[0]", "below the ground"},
      {medium + object + "[camera]\nposition = [0, 0, 0.5]\nlook_at = [0, 0, 1]\n", "objects[0]", "camera is inside"},
      {medium + object + "[light]\nenvironment = \"sky.exr\"\n", "light.environment", "no such file"},
  };
  for (const auto& [text, key, why] : cases) {
    const std::string path = write("bad.toml", text);
    try {
      const scene::RenderScene sc = scene::read_render_scene(path);
      const render::SceneGeometry geometry(sc, render::FreeRadius::kGrid, 16);
      ADD_FAILURE() << "accepted: " << text;
    } catch (const scene::SceneError& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find(path), std::string::npos) << m;
      EXPECT_NE(m.find(key), std::string::npos) << m;
      EXPECT_NE(m.find(why), std::string::npos) << m;
      EXPECT_EQ(m.find('\n'), std::string::npos) << m;
    }
  }
}

}  // namespace
