// `stf render SCENE.toml` (docs/render.md "Scenes", docs/scenes.md "Render scenes"): the strided
// image of a mesh in colour agrees with brute force, the image layout, and bad scenes.
#include <H5Cpp.h>

#include "cli_fixture.h"
#include "image_compare.h"
#include "stf/core/h5io.h"
#include "strided_scene.h"

namespace {

const std::string kScene = R"([camera]
position = [0, 0.5, 3]
look_at = [0, 0, 0]
fov = 40
width = 24
height = 24
[light]
sky = [0.6, 0.7, 0.8]
sun_direction = [1, 1.5, 0.5]
sun_radiance = 30
)" + stf::test::strided_objects();

struct Rendered {
  std::vector<double> mean, variance_of_mean;
};

Rendered read_rgb(const std::string& path, hsize_t h, hsize_t w) {
  H5::H5File f(path, H5F_ACC_RDONLY);
  return {stf::h5::get_dataset(f, "/image/mean", {h, w, 3}), stf::h5::get_dataset(f, "/image/variance_of_mean", {h, w, 3})};
}

class SceneRenderCli : public Cli {
 protected:
  std::string scene() {
    std::ofstream(out("scene.toml")) << kScene;
    return out("scene.toml");
  }
};

TEST_F(SceneRenderCli, StridedMeshInColourAgreesWithBruteForce) {
  const std::string common = "render " + scene() + " --spp 600 --quiet ";
  Result b = stf(common + "--seed 1 --method brute -o " + out("b.h5"));
  ASSERT_EQ(b.status, 0) << b.err;
  Result s = stf(common + "--seed 2 --method stf --pack " + std::string(STF_RENDER_PACK) + " -o " + out("s.h5") +
                 " --json " + out("s.json"));
  ASSERT_EQ(s.status, 0) << s.err;
  std::ifstream json(out("s.json"));
  const std::string stats((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
  EXPECT_EQ(stats.find("\"strides\": 0,"), std::string::npos) << stats;
  const Rendered rb = read_rgb(out("b.h5"), 24, 24), rs = read_rgb(out("s.h5"), 24, 24);
  const ImageComparison r = compare_images(rb.mean, rb.variance_of_mean, rs.mean, rs.variance_of_mean, 24, 24, 3, 4);
  EXPECT_GT(r.blocks, 90);
  EXPECT_LT(r.max_block_z, 4.5);
  for (int c = 0; c < 3; ++c) {
    EXPECT_LT(std::abs(r.mean_z[std::size_t(c)]), 4.5) << c;
    EXPECT_NEAR(r.mean_ratio[std::size_t(c)], 1, 0.01) << c;
  }
}

// Ideal strides (the true transport through each sphere) are exact: their image is brute force's
// within noise, and their collisions inside spheres are counted apart.
TEST_F(SceneRenderCli, IdealStridesDrawTheBruteForceImage) {
  const std::string common = "render " + scene() + " --spp 300 --quiet ";
  ASSERT_EQ(stf(common + "--seed 3 --method brute -o " + out("b.h5")).status, 0);
  Result s = stf(common + "--seed 4 --method stf --ideal-strides --pack " + std::string(STF_RENDER_PACK) + " -o " +
                 out("i.h5") + " --json " + out("i.json"));
  ASSERT_EQ(s.status, 0) << s.err;
  std::ifstream json(out("i.json"));
  const std::string stats((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
  EXPECT_EQ(stats.find("\"ideal_collisions\": 0,"), std::string::npos) << stats;
  const Rendered rb = read_rgb(out("b.h5"), 24, 24), ri = read_rgb(out("i.h5"), 24, 24);
  const ImageComparison r = compare_images(rb.mean, rb.variance_of_mean, ri.mean, ri.variance_of_mean, 24, 24, 3, 4);
  EXPECT_LT(r.max_block_z, 4.5);
  for (int c = 0; c < 3; ++c) EXPECT_LT(std::abs(r.mean_z[std::size_t(c)]), 4.5) << c;
}

// One scene format: `stf build SCENE.toml` on a render scene builds the pack `stf render` uses.
// After the build, the render finds every sphere in the cache (it computes none), and its image
// is bit for bit the image drawn through the built pack.
TEST_F(SceneRenderCli, BuildOfARenderSceneIsThePackTheRenderUses) {
  const std::string settings = " --tolerance 0.3 --model vmf:auto --cache " + out("cache");
  Result b = stf("build " + scene() + settings + " --quiet -o " + out("p.stfpack"));
  ASSERT_EQ(b.status, 0) << b.err;
  const std::string common = "render " + scene() + " --method stf --spp 4 --width 12 --height 12 --quiet ";
  Result r = stf(common + settings + " -o " + out("a.h5") + " --json " + out("a.json"));
  ASSERT_EQ(r.status, 0) << r.err;
  std::ifstream json(out("a.json"));
  const std::string stats((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
  EXPECT_NE(stats.find("\"spheres_computed\": 0,"), std::string::npos) << stats;
  EXPECT_EQ(stats.find("\"strides\": 0,"), std::string::npos) << stats;
  ASSERT_EQ(stf(common + "--pack " + out("p.stfpack") + " -o " + out("b.h5")).status, 0);
  EXPECT_EQ(read_rgb(out("a.h5"), 12, 12).mean, read_rgb(out("b.h5"), 12, 12).mean);
  // A recipe sets its own tolerance and model.
  std::ofstream(out("recipe.toml")) << "[[media]]\nname = \"m\"\nsigma_s = 8\nsigma_a = 0.1\ng = 0.5\nsize = 1\n";
  Result refused = stf("build " + out("recipe.toml") + " --tolerance 0.3 --plan-only");
  EXPECT_EQ(refused.status, 2);
  EXPECT_NE(refused.err.find("[settings]"), std::string::npos) << refused.err;
}

// The README's "Render your own mesh" scene, as printed there, with a shipped mesh as my.obj:
// it renders, and `stf build` plans its pack.
TEST_F(SceneRenderCli, TheReadmesOwnMeshSceneRendersAndBuilds) {
  std::ifstream readme(std::string(STF_SOURCE_DIR) + "/README.md");
  const std::string text((std::istreambuf_iterator<char>(readme)), std::istreambuf_iterator<char>());
  const std::size_t section = text.find("## Render your own mesh");
  ASSERT_NE(section, std::string::npos);
  const std::size_t open = text.find("```toml\n", section), close = text.find("```", open + 8);
  ASSERT_LT(close, text.find("\n## ", section + 1));
  std::ofstream(out("my_scene.toml")) << text.substr(open + 8, close - open - 8);
  std::filesystem::copy_file(std::string(STF_SOURCE_DIR) + "/data/scenes/meshes/icosphere.obj", out("my.obj"));
  Result r = stf("render " + out("my_scene.toml") + " --method brute --spp 2 --width 16 --height 16 --quiet -o " + out("m.h5"));
  ASSERT_EQ(r.status, 0) << r.err;
  const Rendered m = read_rgb(out("m.h5"), 16, 16);
  for (double v : m.mean) EXPECT_TRUE(std::isfinite(v) && v >= 0);
  Result plan = stf("build " + out("my_scene.toml") + " --plan-only --cache " + out("cache"));
  EXPECT_EQ(plan.status, 0) << plan.err;
  EXPECT_NE(plan.err.find("milk (R)"), std::string::npos) << plan.err;
}

TEST_F(SceneRenderCli, WritesRgbLayoutAndImages) {
  Result r = stf("render " + scene() + " --spp 3 --width 10 --height 6 --method brute --quiet -o " + out("i.h5") +
                 " --exr " + out("i.exr") + " --png " + out("i.png"));
  ASSERT_EQ(r.status, 0) << r.err;
  H5::H5File f(out("i.h5"), H5F_ACC_RDONLY);
  EXPECT_EQ(stf::h5::dataset_shape(f, "/image/mean"), (std::vector<hsize_t>{6, 10, 3}));
  EXPECT_EQ(stf::h5::dataset_shape(f, "/image/variance_of_mean"), (std::vector<hsize_t>{6, 10, 3}));
  EXPECT_EQ(stf::h5::get_string(f, "scene"), "scene.toml");
  EXPECT_EQ(stf::h5::get_string(f, "method"), "brute");
  EXPECT_GT(fs::file_size(out("i.exr")), 0u);
  EXPECT_GT(fs::file_size(out("i.png")), 0u);
}

TEST_F(SceneRenderCli, BadScenesAndFlagsAreOneLineAndNoFile) {
  std::ofstream(out("other.toml")) << "[[media]]\nname = \"m\"\nsigma_s = 1\nsigma_a = 0.1\ng = 0.3\n"
                                      "[[objects]]\nshape = \"sphere\"\nmedium = \"m\"\n";
  std::ofstream(out("bad.toml")) << "[[media]]\nname = \"m\"\nsigma_s = 1\nsigma_a = 0.1\ng = 0.5\n"
                                    "[[objects]]\nshape = \"cube\"\nmedium = \"m\"\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"render " + out("bad.toml") + " --spp 1 --method brute", "objects[0].shape"},
      {"render " + scene() + " --spp 1 --method brute --sigma-s 3", "--sigma-s"},
      {"render " + scene() + " --spp 1 --method brute --free-radius exact", "--free-radius"},
      {"render --spp 1 --method brute", "scene file"},
      {"render " + scene() + " --spp 1 --method brute --ideal-strides", "--ideal-strides"},
      {"render " + out("other.toml") + " --spp 1 --method stf --pack " + std::string(STF_RENDER_PACK), "--pack"},
  };
  for (const auto& [args, names] : cases) {
    Result r = stf(args + " -o " + out("i.h5") + " --png " + out("i.png"));
    EXPECT_EQ(r.status, 2) << args << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << args << "\n" << r.err;
    EXPECT_NE(r.err.find(names), std::string::npos) << args << "\n" << r.err;
    EXPECT_FALSE(fs::exists(out("i.h5"))) << args;
    EXPECT_FALSE(fs::exists(out("i.png"))) << args;
  }
}

}  // namespace
