// Environment maps (stf/render/environment.h): the map's own sampling against its pdf, and
// scenes lit by a map against exact equivalents.
//  - Directions drawn from a map fall in its texels, and in the quarters of each texel, as the
//    pdf says (chi-square); the pdf a draw reports is pdf() of its direction; the pdf integrates
//    to 1 over the sphere; radiance() is the texel's value.
//  - A constant map is a uniform sky: the two draw the same image.
//  - With a map, next-event estimation (its shadow rays drawn from the map, weighted by the power
//    heuristic) draws the image of escaping paths alone.
//  - Maps that cannot be read, or hold negative or non-finite radiance, are refused in one line.
#include <gtest/gtest.h>

#include <fstream>

#include "chi2.h"
#include "image_compare.h"
#include "scene_fixture.h"
#include "stf/render/environment.h"
#include "stf/render/image_file.h"
#include "stf/scene/scene_error.h"

namespace {

using namespace stf;

struct Uniforms {
  render::PixelRng rng{91, 0};
  double operator()() { return rng.uniform(); }
};

// An 8 x 4 map: a bright texel, a black one, and a gradient elsewhere.
render::EnvironmentMap test_map() {
  std::vector<float> rgb;
  for (int t = 0; t < 32; ++t)
    for (int c = 0; c < 3; ++c) rgb.push_back(t == 9 ? 40.0f : t == 20 ? 0.0f : float(0.2 + 0.05 * t + 0.1 * c));
  return render::EnvironmentMap(8, 4, rgb);
}

// The texel of a direction and its quarter (halves of its azimuth and polar ranges).
int quarter_texel(const Vec3& d, int width, int height) {
  const double theta = std::acos(std::clamp(d.y, -1.0, 1.0)) / kPi * height;
  const double phi = (std::atan2(d.x, -d.z) + kPi) / (2 * kPi) * width;
  const int v = std::min(height - 1, int(theta)), u = std::min(width - 1, int(phi));
  return ((v * width + u) * 2 + (theta - v >= 0.5)) * 2 + (phi - u >= 0.5);
}

TEST(Environment, DrawsWhatItsPdfSaysChiSquare) {
  const render::EnvironmentMap map = test_map();
  const int n = 400000;
  std::vector<double> observed(32 * 4, 0.0), expected(32 * 4, 0.0);
  // Each quarter's probability: the pdf integrated over it (8 x 8 midpoints in phi, theta).
  for (int q = 0; q < 32 * 4; ++q) {
    const int texel = q / 4, v = texel / 8, u = texel % 8;
    const double t0 = kPi * (v + 0.5 * ((q / 2) % 2)) / 4, p0 = 2 * kPi * (u + 0.5 * (q % 2)) / 8 - kPi;
    for (int i = 0; i < 64; ++i) {
      const double theta = t0 + kPi / 8 * ((i / 8) + 0.5) / 8, phi = p0 + kPi / 8 * ((i % 8) + 0.5) / 8;
      const Vec3 d{std::sin(theta) * std::sin(phi), std::cos(theta), -std::sin(theta) * std::cos(phi)};
      expected[std::size_t(q)] += map.pdf(d) * std::sin(theta) * (kPi / 64) * (kPi / 64) * n;
    }
  }
  Uniforms u;
  for (int i = 0; i < n; ++i) {
    double pdf;
    const double u1 = u(), u2 = u();
    const Vec3 d = map.sample(u1, u2, pdf);
    ASSERT_NEAR(pdf, map.pdf(d), 1e-9 * pdf) << i;
    ASSERT_NEAR(length(d), 1, 1e-12);
    observed[std::size_t(quarter_texel(d, 8, 4))] += 1;
  }
  EXPECT_EQ(observed[20 * 4] + observed[20 * 4 + 1] + observed[20 * 4 + 2] + observed[20 * 4 + 3], 0);  // black
  const test::Chi2Result r = test::chi2_test(observed, expected);
  EXPECT_GT(r.p_value, test::kChi2Alpha) << r.describe();
}

TEST(Environment, PdfIntegratesToOneAndRadianceIsTheTexels) {
  const render::EnvironmentMap map = test_map();
  // Uniform directions: the mean of 4 pi pdf is 1 (the bright texel is drawn 1 in 30: its
  // variance is what the tolerance allows for).
  Uniforms u;
  const int n = 2000000;
  double sum = 0, sum2 = 0;
  for (int i = 0; i < n; ++i) {
    const double z = 2 * u() - 1, phi = 2 * kPi * u(), r = std::sqrt(1 - z * z);
    const double f = 4 * kPi * map.pdf({r * std::cos(phi), z, r * std::sin(phi)});
    sum += f, sum2 += f * f;
  }
  const double mean = sum / n, sd = std::sqrt((sum2 / n - mean * mean) / n);
  EXPECT_NEAR(mean, 1, 5 * sd);
  for (int v = 0; v < 4; ++v)
    for (int t = 0; t < 8; ++t) {
      const double theta = kPi * (v + 0.5) / 4, phi = 2 * kPi * (t + 0.5) / 8 - kPi;
      const Vec3 d{std::sin(theta) * std::sin(phi), std::cos(theta), -std::sin(theta) * std::cos(phi)};
      const int texel = v * 8 + t;
      EXPECT_EQ(map.radiance(d, 1), texel == 9 ? 40.0f : texel == 20 ? 0.0f : float(0.2 + 0.05 * texel + 0.1));
    }
  // A black map draws nothing.
  const render::EnvironmentMap black(2, 1, std::vector<float>(6, 0.0f));
  double pdf = 1;
  black.sample(0.3, 0.6, pdf);
  EXPECT_EQ(pdf, 0);
  EXPECT_EQ(black.pdf({0, 0, -1}), 0);
}

class EnvironmentScene : public test::SceneFixture {
 protected:
  // An EXR of [height * width * 3] values.
  void write_map(const std::string& name, int width, int height, const std::vector<double>& rgb) const {
    render::write_exr(path(name), {rgb, width, height, 3});
  }
};

std::string scene_with(const std::string& light) {
  return test::lit_box_scene(light + "\nsun_direction = [1, 2, 0.5]\nsun_radiance = [30, 25, 20]");
}

void expect_same_image(const render::Image& a, const render::Image& b) {
  const ImageComparison r = compare_images(a.mean, a.variance_of_mean, b.mean, b.variance_of_mean, 24, 24, 3, 4);
  EXPECT_GT(r.blocks, 80);
  EXPECT_LT(r.max_block_z, 4.5);
  for (int c = 0; c < 3; ++c) EXPECT_LT(std::abs(r.mean_z[std::size_t(c)]), 4.5) << c;
}

TEST_F(EnvironmentScene, AConstantMapIsAUniformSky) {
  std::vector<double> rgb;
  for (int t = 0; t < 16 * 8; ++t) rgb.insert(rgb.end(), {0.8, 0.5, 0.3});
  write_map("constant.exr", 16, 8, rgb);
  const render::Image sky = draw(scene_with("sky = [0.4, 0.25, 0.15]"), 300, 11);
  const render::Image map = draw(scene_with("environment = \"constant.exr\"\nenvironment_scale = 0.5"), 300, 12);
  EXPECT_GT(map.shadow_rays, sky.shadow_rays);  // the map's shadow rays too
  expect_same_image(sky, map);
}

TEST_F(EnvironmentScene, NextEventEstimationDrawsTheImageOfEscapingPaths) {
  // A dim sky with a bright patch low on one side, which lights the ground and the box.
  write_map("patch.exr", 32, 16, test::patch_sky(1, 60));
  const std::string scene = scene_with("environment = \"patch.exr\"");
  const render::Image with = draw(scene, 300, 13, true), without = draw(scene, 1200, 14, false);
  EXPECT_EQ(without.shadow_rays, 0);
  expect_same_image(without, with);
}

TEST_F(EnvironmentScene, BadMapsAreRefusedInOneLine) {
  std::ofstream(path("text.exr")) << "not an image\n";
  write_map("negative.exr", 2, 1, {1, 1, 1, 1, -0.5, 1});
  std::ofstream(path("ok.exr"));
  const std::vector<std::tuple<std::string, std::string, std::string>> cases = {
      {"environment = \"missing.exr\"", "light.environment", "no such file"},
      {"environment = \"text.exr\"", "light.environment", "text.exr"},
      {"environment = \"negative.exr\"", "light.environment", "finite and >= 0"},
      {"environment = \"negative.exr\"\nsky = 1", "light.sky", "give one of sky and environment"},
      {"sky = 1\nenvironment_scale = 2", "light.environment_scale", "no environment map"},
  };
  for (const auto& [light, key, why] : cases) {
    try {
      std::ofstream(path("bad.toml")) << scene_with(light);
      const scene::RenderScene sc = scene::read_render_scene(path("bad.toml"));
      const render::SceneGeometry geometry(sc, render::FreeRadius::kGrid, 16);
      const render::ScenePaths paths(sc, geometry);
      ADD_FAILURE() << "accepted: " << light;
    } catch (const scene::SceneError& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find(path("bad.toml")), std::string::npos) << m;
      EXPECT_NE(m.find(key), std::string::npos) << m;
      EXPECT_NE(m.find(why), std::string::npos) << m;
      EXPECT_EQ(m.find('\n'), std::string::npos) << m;
    }
  }
}

}  // namespace
