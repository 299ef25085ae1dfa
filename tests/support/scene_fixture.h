// What the render-scene tests share: a scratch folder, scene files written into it and rendered
// by either method's paths, and a lit scene of a milky rounded box on a ground.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "stf/render/render.h"
#include "stf/render/scene_geometry.h"
#include "stf/render/scene_paths.h"
#include "stf/scene/render_scene.h"

namespace stf::test {

inline const std::string kMeshes = std::string(STF_SOURCE_DIR) + "/data/scenes/meshes/";
inline const std::string kCamera = "[camera]\nposition = [0, 0.4, 2.2]\nlook_at = [0, 0, 0]\nfov = 35\n";

// The rounded box of a milky medium on a coloured ground, under the [light] table's `light`.
inline std::string lit_box_scene(const std::string& light) {
  return kCamera + "[light]\n" + light + R"(
[[media]]
name = "milky"
sigma_s = [12, 9, 6]
sigma_a = [0.05, 0.1, 0.4]
g = 0.6
[[objects]]
mesh = ")" + kMeshes + R"(rounded_box.obj"
medium = "milky"
[ground]
height = -0.36
albedo = [0.7, 0.6, 0.5]
)";
}

// A 32 x 16 latitude-longitude map (RGB, row 0 at the top): a dim sky, `dim` times (0.3, 0.4,
// 0.6), with a patch of about `bright` low on one side.
inline std::vector<double> patch_sky(double dim, double bright) {
  std::vector<double> rgb;
  for (int v = 0; v < 16; ++v)
    for (int u = 0; u < 32; ++u) {
      const double b = v >= 5 && v < 7 && u >= 20 && u < 23 ? bright : 0.0;
      rgb.insert(rgb.end(), {dim * 0.3 + b, dim * 0.4 + 0.8 * b, dim * 0.6 + 0.5 * b});
    }
  return rgb;
}

class SceneFixture : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("stf-scene-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream(path(name)) << text;
    return path(name);
  }
  // The scene `scene_text` at size x size pixels, brute force, on two threads.
  render::Image draw(const std::string& scene_text, int spp, std::uint64_t seed, bool next_event = true,
                     int size = 24) const {
    return draw_with(scene_text, nullptr, render::PathOptions{next_event, false}, spp, seed, size);
  }
  // The same in strides through `pack` (brute force where null), with `options`.
  render::Image draw_with(const std::string& scene_text, const std::vector<PackEntry>* pack, render::PathOptions options,
                          int spp, std::uint64_t seed, int size = 24) const {
    const scene::RenderScene sc = scene::read_render_scene(write("scene.toml", scene_text));
    const render::SceneGeometry geometry(sc, render::FreeRadius::kGrid, 64);
    const render::ScenePaths paths(sc, geometry, pack, options);
    render::ImageSettings s;
    s.width = s.height = size, s.spp = spp, s.seed = seed, s.run.threads = 2;
    return render::render(sc, paths, s);
  }
  std::filesystem::path dir_;
};

}  // namespace stf::test
