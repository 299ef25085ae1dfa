// Render scenes, OBJ meshes and environment maps stf did not write, through the scene reader,
// the mesh reader, the placement checks and the renderer, all built from their own sources
// under AddressSanitizer and UndefinedBehaviorSanitizer. Structured mutations give every value
// of the scene, every token of the mesh and every field of the map's header hostile values;
// byte flips and truncations do the rest. Every case loads and renders a 4 x 4 image at 1 spp
// with finite pixels, or fails with one line naming the file that was mutated; a case running
// past its time limit fails the test (SIGALRM). A scene that loads but whose medium is too dense
// for a brute-force case (optical size above kMaxTau) is counted apart, not rendered.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "stf/core/rng.h"
#include "stf/geometry/mesh.h"
#include "stf/geometry/shipped_meshes.h"
#include "stf/render/render.h"
#include "stf/render/scene_geometry.h"
#include "stf/render/scene_paths.h"
#include "stf/scene/render_scene.h"

namespace stf {
namespace {

namespace fs = std::filesystem;

char current_case[256];
constexpr unsigned kCaseSeconds = 20;
constexpr double kMaxTau = 200;

void on_alarm(int) {
  const char head[] = "scene_fuzz_test: a case ran past its time limit (a hang): ";
  [[maybe_unused]] ssize_t n = ::write(STDERR_FILENO, head, sizeof head - 1);
  n = ::write(STDERR_FILENO, current_case, std::strlen(current_case));
  n = ::write(STDERR_FILENO, "\n", 1);
  ::_exit(1);
}

const char* const kScene = R"(# a scene with every kind of object, light and file
[camera]
position = [0, 0.2, 3]
look_at = [0, 0, 0]
up = [0, 1, 0]
fov = 30
width = 4
height = 4

[light]
environment = "sky.pfm"
environment_scale = 1.5
sun_direction = [1, 1, -1]
sun_radiance = [20, 18, 15]
sun_angle = 5

[ground]
height = -1
albedo = 0.5

[[media]]
name = "milky"
sigma_s = [8, 9, 10]
sigma_a = 0.1
g = 0.5

[[media]]
name = "marble"
preset = "marble"
density = 0.5

[[objects]]
mesh = "ball.obj"
scale = 1
translate = [-0.6, 0, 0]
medium = "milky"
ior = 1.3

[[objects]]
shape = "sphere"
radius = 0.4
translate = [0.6, 0, 0]
medium = "marble"
)";

// A small latitude-longitude map as PFM: a header and little-endian floats, bottom row first.
std::string sky_map(int width, int height) {
  std::string bytes = "PF\n" + std::to_string(width) + " " + std::to_string(height) + "\n-1.0\n";
  for (int i = 0; i < width * height * 3; ++i) {
    const float v = 0.2f + 0.1f * float(i % 7);
    bytes.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  return bytes;
}

const char* const kValues[] = {"nan", "inf", "-inf", "-1", "0", "1e300", "1e-300", "\"x\"", "[]", "[1, 2]", "{}",
                               "true", "1.5", "\"\\u0000\"", "\"a\\nb\"", "[[[[1]]]]", "[1, [2, 3], \"x\"]",
                               "\"sky.pfm\"", "\"ball.obj\"", "\".\"", "\"/dev/zero\"", "1e9", "8193", "-1e10"};
const char* const kTokens[] = {"nan", "inf", "-inf", "1e39", "x", "1e-320", "99999999999999999999", "-99999", "0",
                               "1/2/3", "-1", "1//", "/", "0x10", "+1", "1e400"};

class SceneFuzz : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("stf-scene-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    ::signal(SIGALRM, on_alarm);
    scene_ = kScene;
    mesh_ = geometry::obj_text(geometry::icosphere(0.5, 1));
    map_ = sky_map(8, 4);
  }
  void TearDown() override {
    ::alarm(0);
    fs::remove_all(dir_);
    std::printf("%s: %d cases rendered, %d refused, %d too dense to render by brute force\n",
                ::testing::UnitTest::GetInstance()->current_test_info()->name(), rendered_, refused_, dense_);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  static void write(const std::string& file, const std::string& bytes) {
    std::ofstream(file, std::ios::binary | std::ios::trunc).write(bytes.data(), std::streamsize(bytes.size()));
  }

  // The three files, one of them (`mutated`: "scene.toml", "ball.obj" or "sky.pfm") replaced by
  // `bytes`, through the reader and a 4 x 4 render.
  void run_case(const std::string& name, const std::string& mutated, const std::string& bytes) {
    std::snprintf(current_case, sizeof current_case, "%s", name.c_str());
    write(path("scene.toml"), mutated == "scene.toml" ? bytes : scene_);
    write(path("ball.obj"), mutated == "ball.obj" ? bytes : mesh_);
    write(path("sky.pfm"), mutated == "sky.pfm" ? bytes : map_);
    ::alarm(kCaseSeconds);
    try {
      render_once();
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(path(mutated)), std::string::npos) << name << ": " << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << name << ": " << what;
      ++refused_;
    }
    ::alarm(0);
  }

  void render_once() {
    const scene::RenderScene sc = scene::read_render_scene(path("scene.toml"));
    const render::SceneGeometry geometry(sc, render::FreeRadius::kGrid, 16);
    const render::ScenePaths paths(sc, geometry);
    for (std::size_t i = 0; i < sc.objects.size(); ++i)
      for (int c = 0; c < 3; ++c)
        if (sc.media[std::size_t(sc.objects[i].medium)].sigma_t(c) * geometry.largest_free_radius(int(i)) > kMaxTau) {
          ++dense_;
          return;
        }
    render::ImageSettings s;
    s.width = s.height = 4, s.spp = 1, s.run.threads = 1;
    const render::Image image = render::render(sc, paths, s);
    for (double v : image.mean) EXPECT_TRUE(std::isfinite(v)) << current_case;
    ++rendered_;
  }

  // Byte flips (1 to 4 bytes at seeded places to seeded values) and truncations of `base`.
  void flip_and_truncate(const std::string& file, const std::string& base, int flips, std::uint64_t seed) {
    for (int k = 0; k < flips; ++k) {
      std::string bytes = base;
      const int n = 1 + int(splitmix64(seed) % 4);
      for (int j = 0; j < n; ++j) bytes[splitmix64(seed) % bytes.size()] = char(splitmix64(seed) % 256);
      run_case(file + " flip " + std::to_string(k), file, bytes);
    }
    for (std::size_t cut = 0; cut < base.size(); cut += std::max<std::size_t>(1, base.size() / 40))
      run_case(file + " cut at " + std::to_string(cut), file, base.substr(0, cut));
  }

  fs::path dir_;
  std::string scene_, mesh_, map_;
  int rendered_ = 0, refused_ = 0, dense_ = 0;
};

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::string joined(const std::vector<std::string>& lines) {
  std::string out;
  for (const std::string& l : lines) out += l + "\n";
  return out;
}

TEST_F(SceneFuzz, TheUnmutatedFilesRender) {
  run_case("unmutated", "scene.toml", scene_);
  EXPECT_EQ(rendered_, 1);
}

TEST_F(SceneFuzz, ScenesWithEveryValueMutatedLoadOrFailInOneLine) {
  const std::vector<std::string> lines = lines_of(scene_);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    std::vector<std::string> edited = lines;
    edited.erase(edited.begin() + std::ptrdiff_t(i));
    run_case("scene without line " + std::to_string(i + 1), "scene.toml", joined(edited));
    edited = lines;
    edited.insert(edited.begin() + std::ptrdiff_t(i), lines[i]);
    run_case("scene with line " + std::to_string(i + 1) + " twice", "scene.toml", joined(edited));
    const std::size_t eq = lines[i].find(" = ");
    if (eq == std::string::npos) continue;
    for (const char* value : kValues) {
      edited = lines;
      edited[i] = lines[i].substr(0, eq + 3) + value;
      run_case("scene line " + std::to_string(i + 1) + " = " + value, "scene.toml", joined(edited));
    }
  }
}

TEST_F(SceneFuzz, ScenesNestedDeepOrFlippedLoadOrFailInOneLine) {
  const int deep = 10000;
  const std::vector<std::string> nested = {
      "a = " + std::string(deep, '[') + std::string(deep, ']') + "\n",
      "a = " + [&] {
        std::string s;
        for (int i = 0; i < deep; ++i) s += "{b = ";
        return s + "1" + std::string(deep, '}');
      }() + "\n",
      [&] {
        std::string s = "a";
        for (int i = 0; i < deep; ++i) s += ".a";
        return s + " = 1\n";
      }(),
      [&] {
        std::string s = "[a";
        for (int i = 0; i < deep; ++i) s += ".a";
        return s + "]\n";
      }(),
  };
  for (std::size_t k = 0; k < nested.size(); ++k) {
    run_case("nested " + std::to_string(k), "scene.toml", nested[k]);
    run_case("nested " + std::to_string(k) + " after the scene", "scene.toml", scene_ + nested[k]);
  }
  flip_and_truncate("scene.toml", scene_, 300, 11);
}

TEST_F(SceneFuzz, MeshesWithEveryTokenMutatedLoadOrFailInOneLine) {
  const std::vector<std::string> lines = lines_of(mesh_);
  for (std::size_t i = 1; i < lines.size(); i += 3) {  // every third line: vertices and faces alike
    std::vector<std::string> edited = lines;
    edited.erase(edited.begin() + std::ptrdiff_t(i));
    run_case("mesh without line " + std::to_string(i + 1), "ball.obj", joined(edited));
    for (const char* token : kTokens) {
      std::istringstream words(lines[i]);
      std::vector<std::string> w;
      for (std::string x; words >> x;) w.push_back(x);
      const std::size_t at = 1 + i % 3 % (w.size() - 1);
      w[at] = token;
      std::string line;
      for (const std::string& x : w) line += x + " ";
      edited = lines;
      edited[i] = line;
      run_case("mesh line " + std::to_string(i + 1) + " word " + std::to_string(at) + " " + token, "ball.obj",
               joined(edited));
    }
  }
  ASSERT_EQ(::mkfifo(path("pipe.mtl").c_str(), 0600), 0);
  run_case("mesh with an mtllib that is a FIFO", "ball.obj", "mtllib pipe.mtl\n" + mesh_);
  flip_and_truncate("ball.obj", mesh_, 200, 12);
}

TEST_F(SceneFuzz, MapsWithEveryHeaderFieldMutatedLoadOrFailInOneLine) {
  const std::string pixels = map_.substr(map_.find("-1.0\n") + 5);
  for (const char* kind : {"PF", "Pf", "P6", "P3", "PX", ""})
    for (const char* size : {"8 4", "18000 18000", "0 4", "-8 4", "8", "x y", "99999999999 1", "4 8"})
      for (const char* scale : {"-1.0", "1.0", "0", "nan", "-1e300"})
        run_case(std::string("map ") + kind + " " + size + " " + scale, "sky.pfm",
                 std::string(kind) + "\n" + size + "\n" + scale + "\n" + pixels);
  flip_and_truncate("sky.pfm", map_, 150, 13);
}

}  // namespace
}  // namespace stf
