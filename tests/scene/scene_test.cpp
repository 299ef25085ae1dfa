// Scene files, planning, the cache, and the render-time lookup.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <functional>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "stf/scene/build.h"
#include "stf/scene/plan.h"
#include "stf/scene/scene.h"
#include "stf/lookup.h"

namespace fs = std::filesystem;

namespace stf::scene {
namespace {

class SceneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) / ("stf_scene_" + std::to_string(::getpid()) + "_" +
                                            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& text) {
    std::ofstream((dir_ / name).string()) << text;
    return (dir_ / name).string();
  }
  fs::path dir_;
};

const char* kTiny = R"([settings]
paths = 3000
grid = "healpix:2"
alpha_bins = 6
model = "vmf:1"

[[media]]
name = "a"
sigma_s = 10.0
sigma_a = 1.0
g = 0.5
radius_min = 0.2
radius_max = 1.0

[[media]]
name = "a_twice_as_dense"
sigma_s = 20.0
sigma_a = 2.0
g = 0.5
radius_min = 0.1
radius_max = 0.5

[[media]]
name = "thin"
sigma_s = 0.5
sigma_a = 0.0
g = 0.0
size = 1.0
)";

TEST_F(SceneTest, BadScenesNameFileLineAndKey) {
  struct Case {
    std::string text, expect_key;
    int line;
  };
  const Case cases[] = {
      {"[[media]]\nname = \"m\"\nsigma_s = 1.0\nsigma_a = 0.0\ng = 0.2\nsize = 1.0\ncolour = \"red\"\n", "colour", 7},
      {"[[media]]\nname = \"m\"\nsigma_s = 1.0\ng = 0.2\nsize = 1.0\n", "sigma_a", 1},
      {"[[media]]\nname = \"m\"\nsigma_s = 1.0\nsigma_a = 0.0\ng = 1.5\nsize = 1.0\n", "g", 5},
      {"[[media]]\nname = \"m\"\nsigma_s = -1.0\nsigma_a = 0.0\ng = 0.1\nsize = 1.0\n", "sigma_s", 3},
      {"[settings]\npaths = 0\n[[media]]\nname = \"m\"\nsigma_s = 1.0\nsigma_a = 0.0\ng = 0.1\nsize = 1.0\n", "paths", 2},
      {"[settings]\ngrid = \"hex:3\"\n[[media]]\nname = \"m\"\nsigma_s = 1.0\nsigma_a = 0.0\ng = 0.1\nsize = 1.0\n", "grid", 2},
      {"[[media]]\nname = \"m\"\nsigma_s = 1.0\nsigma_a = 0.0\ng = 0.1\nradius_min = 2.0\nradius_max = 1.0\n", "radius", 7},
      {"[settings]\ntolerance = 1.5\n[[media]]\nname = \"m\"\nsigma_s = 1.0\nsigma_a = 0.0\ng = 0.1\nsize = 1.0\n", "tolerance", 2},
  };
  for (const Case& c : cases) {
    std::string path = write("bad.toml", c.text);
    try {
      read_scene(path);
      ADD_FAILURE() << "accepted:\n" << c.text;
    } catch (const SceneError& e) {
      std::string what = e.what();
      EXPECT_NE(what.find("bad.toml:" + std::to_string(c.line)), std::string::npos) << what;
      EXPECT_NE(what.find(c.expect_key), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
  try {
    read_scene(write("syntax.toml", "[[media]]\nname = \"m\"\nsigma_s =\n"));
    ADD_FAILURE() << "accepted a syntax error";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("syntax.toml:3:"), std::string::npos) << e.what();
  }
  EXPECT_THROW(read_scene(write("empty.toml", "[settings]\npaths = 10\n")), SceneError);
}

TEST_F(SceneTest, PlanSharesScaledMediaAndSkipsThinOnes) {
  Scene scene = read_scene(write("s.toml", kTiny));
  Plan plan = make_plan(scene, (dir_ / "cache").string());
  int computed = 0;
  for (const PlanEntry& e : plan.entries) {
    if (e.media == std::vector<std::string>{"thin"}) {
      EXPECT_EQ(e.action, "skip");
      EXPECT_NE(e.reason.find("tau_skip"), std::string::npos);
      continue;
    }
    // a (tau 2.2 .. 11) and its denser twin (2.2 .. 11) share tau 2, 4, 8.
    EXPECT_EQ(e.media, (std::vector<std::string>{"a", "a_twice_as_dense"}));
    EXPECT_EQ(e.action, "compute");
    ++computed;
  }
  EXPECT_EQ(computed, 3);
  std::string json = plan_json(plan);
  for (const char* key : {"\"entries\"", "\"tau\"", "\"albedo\"", "\"g\"", "\"action\"", "\"reason\"", "\"media\""})
    EXPECT_NE(json.find(key), std::string::npos) << key;
}

TEST_F(SceneTest, SecondBuildComputesNothingAndEditsRecomputeOnlyWhatChanged) {
  const std::string cache = (dir_ / "cache").string(), pack = (dir_ / "s.stfpack").string();
  std::string path = write("s.toml", kTiny);
  Scene scene = read_scene(path);
  EXPECT_EQ(build(scene, make_plan(scene, cache), pack, 2), 3);
  EXPECT_EQ(build(scene, make_plan(scene, cache), pack, 2), 0);
  // Change one medium's g: its entries are new, the others stay cached.
  std::string edited = kTiny;
  edited.replace(edited.find("g = 0.5\nradius_min = 0.1"), 7, "g = 0.6");
  scene = read_scene(write("s.toml", edited));
  Plan plan = make_plan(scene, cache);
  int cached = 0;
  for (const PlanEntry& e : plan.entries) cached += e.action == "cached";
  EXPECT_EQ(cached, 3);
  EXPECT_EQ(build(scene, plan, pack, 2), 3);
}

// Under a tolerance the settings are limits: each entry is computed at what its certificate
// needs, and the plan of the built scene shows that, within the limits and the tolerance.
TEST_F(SceneTest, ToleranceChoosesEachEntrysResolutionWithinTheLimits) {
  const std::string cache = (dir_ / "cache").string(), pack = (dir_ / "s.stfpack").string();
  std::string text = kTiny;
  text.replace(text.find("paths = 3000"), 12, "paths = 2e5\ntolerance = 0.25");
  text.replace(text.find("grid = \"healpix:2\""), 18, "grid = \"healpix:4\"");
  text.replace(text.find("alpha_bins = 6"), 14, "alpha_bins = 12");
  text.replace(text.find("vmf:1"), 5, "vmf:auto");
  Scene scene = read_scene(write("s.toml", text));
  Plan before = make_plan(scene, cache);
  for (const PlanEntry& e : before.entries) {
    if (e.action == "compute") {
      EXPECT_FALSE(e.resolution.measured);
    }
  }
  EXPECT_EQ(build(scene, before, pack, 2), 3);
  Plan after = make_plan(scene, cache);
  for (const PlanEntry& e : after.entries) {
    if (e.action == "skip") continue;
    EXPECT_EQ(e.action, "cached");
    const Resolution& r = e.resolution;
    EXPECT_TRUE(r.measured);
    EXPECT_LE(r.alpha_bins, 12);
    EXPECT_EQ(12 % r.alpha_bins, 0);
    EXPECT_LE(r.paths, 200000);
    EXPECT_TRUE(r.tolerance_met) << "tau " << e.tau;
    EXPECT_GE(r.tv_bound, 0);
    EXPECT_LE(r.tv_bound, 0.25);
    EXPECT_GT(r.bytes, 0);
  }
  const nlohmann::json plan = nlohmann::json::parse(plan_json(after));
  EXPECT_TRUE(std::any_of(plan["entries"].begin(), plan["entries"].end(),
                          [](const nlohmann::json& e) { return e.contains("resolution") && e["resolution"]["chosen"] == true; }));
}

TEST_F(SceneTest, LookupPicksTheLargestSphereThatFits) {
  const std::string cache = (dir_ / "cache").string(), pack_path = (dir_ / "s.stfpack").string();
  Scene scene = read_scene(write("s.toml", kTiny));
  build(scene, make_plan(scene, cache), pack_path, 2);
  std::vector<PackEntry> pack;
  std::string error;
  ASSERT_TRUE(read_pack_file(pack_path, pack, error)) << error;
  double radius = 0;
  // a: sigma_t = 11, albedo 10 / 11, g 0.5. Free radius 0.5 fits tau 5.5: the tau 4 sphere, radius 4 / 11.
  const double a = 10.0 / 11;
  const PackEntry* e = find_entry(pack, a, 0.5, 11, 0.5, radius);
  ASSERT_NE(e, nullptr);
  EXPECT_EQ(e->model.tau, 4);
  EXPECT_DOUBLE_EQ(radius, 4.0 / 11);
  EXPECT_EQ(find_entry(pack, a, 0.5, 11, 100, radius)->model.tau, 8);
  EXPECT_EQ(find_entry(pack, a, 0.5, 11, 0.1, radius), nullptr);  // tau 1.1: too close to the boundary
  EXPECT_EQ(radius, 0);
  EXPECT_EQ(find_entry(pack, 1.0, 0.0, 0.5, 1, radius), nullptr);  // thin: skipped
  EXPECT_EQ(find_entry(pack, a, 0.4, 11, 1, radius), nullptr);     // another g
  EXPECT_EQ(find_entry(pack, a * (1 - 1e-6), 0.5, 11, 1, radius), nullptr);  // another albedo
  // The inner-loop lookup gives the same sphere and radius at every free radius.
  for (const auto& [albedo, g] : {std::pair{a, 0.5}, {1.0, 0.0}, {0.5, 0.5}}) {
    const SphereLookup lookup(pack, albedo, g);
    for (double free = 0; free < 2; free += 0.01) {
      double r1 = -1, r2 = -1;
      const PackEntry* expected = find_entry(pack, albedo, g, 11, free, r1);
      const int i = lookup.find(11, free, r2);
      EXPECT_EQ(i < 0 ? nullptr : &pack[lookup.pack_index(i)], expected) << albedo << " " << free;
      if (i >= 0) {
        EXPECT_EQ(lookup.sampler(i).model().tau, expected->model.tau);
      }
      EXPECT_EQ(r1, r2);
    }
  }
}

// A lookup never mixes media: spheres of two albedos under one name (what `stf pack` of a
// cache's models once gave) are refused when the pack is written, and a lookup by medium
// finds only its own, whatever the entries are called.
TEST_F(SceneTest, LookupsCannotMixMedia) {
  const std::string cache = (dir_ / "cache").string(), pack_path = (dir_ / "s.stfpack").string();
  Scene scene = read_scene(write("s.toml", kTiny));
  scene.media[1].sigma_a = 4;  // albedo 20 / 24: another medium
  build(scene, make_plan(scene, cache), pack_path, 2);
  std::vector<PackEntry> pack;
  std::string error;
  ASSERT_TRUE(read_pack_file(pack_path, pack, error)) << error;
  std::vector<PackEntry> unnamed = pack;
  for (PackEntry& e : unnamed) e.name = "";
  EXPECT_THROW(write_pack(unnamed), std::invalid_argument);
  EXPECT_NE(pack_entries_error(unnamed).find("two media"), std::string::npos) << pack_entries_error(unnamed);
  for (PackEntry& e : unnamed) e.name = medium_name(e.model.albedo, e.model.g);
  EXPECT_EQ(pack_entries_error(unnamed), "");
  for (const double albedo : {10.0 / 11, 20.0 / 24}) {
    const SphereLookup lookup(pack, albedo, 0.5);
    ASSERT_GT(lookup.size(), 0);
    for (int i = 0; i < lookup.size(); ++i) EXPECT_DOUBLE_EQ(lookup.sampler(i).model().albedo, albedo);
  }
}

}  // namespace
}  // namespace stf::scene
