// `stf render` (docs/render.md, docs/formats.md): the strided image against the brute-force one, the image layout,
// the PNG, and bad input.
#include <H5Cpp.h>

#include <cmath>
#include <map>

#include "cli_fixture.h"
#include "stf/core/h5io.h"

namespace {

// A sphere of optical radius 8; the pack of its tau 2 and 4 spheres is tests/cli/render_scene.toml's.
const std::string kThick = "--sigma-s 7.92 --sigma-a 0.08 --g 0.5 --width 32 --height 32 ";

struct RenderedImage {
  std::vector<double> mean, variance_of_mean;
};

RenderedImage read_image(const std::string& path, hsize_t height, hsize_t width) {
  H5::H5File f(path, H5F_ACC_RDONLY);
  return {stf::h5::get_dataset(f, "/image/mean", {height, width}),
          stf::h5::get_dataset(f, "/image/variance_of_mean", {height, width})};
}

class Render : public Cli {
 protected:
  // ctest builds the pack afresh once for all these tests (the RenderPack fixture); run by hand,
  // the first test builds it where it is missing or older than the binary or the scene.
  static void SetUpTestSuite() {
    const std::string scenes[2] = {STF_RENDER_SCENE, fs::path(STF_RENDER_SCENE).replace_filename("render_scene_lifted.toml")};
    const fs::path packs[2] = {pack(), lifted_pack()};
    bool fresh = true;
    for (int i = 0; i < 2; ++i)
      fresh = fresh && fs::exists(packs[i]) && fs::last_write_time(packs[i]) >= fs::last_write_time(STF_BINARY) &&
              fs::last_write_time(packs[i]) >= fs::last_write_time(scenes[i]);
    if (fresh) return;
    fs::remove_all(pack().parent_path());
    fs::create_directories(pack().parent_path());
    for (int i = 0; i < 2; ++i) {
      const std::string cmd = std::string(STF_BINARY) + " build " + scenes[i] + " --quiet --cache " +
                              (pack().parent_path() / "cache").string() + " -o " + packs[i].string();
      ASSERT_EQ(std::system(cmd.c_str()), 0);
    }
  }
  static fs::path pack() { return STF_RENDER_PACK; }
  static fs::path lifted_pack() { return STF_RENDER_PACK_LIFTED; }

  // The strided image through `strides` against brute force's (b.h5, made by the caller): 4 x 4
  // blocks within 4.5 sigma, the whole image within 1% and 4.5 sigma.
  void expect_agreement(const fs::path& strides, const std::string& common);

  void expect_one_line(const Result& r, const std::string& names, const std::string& what) {
    EXPECT_EQ(r.status, 2) << what << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << what << "\n" << r.err;
    EXPECT_NE(r.err.find(names), std::string::npos) << what << "\n" << r.err;
  }

};

// The targets of the strided method, through plain vMF lobes and through lifted ones (lvmf, drawn
// without retries): no 4 x 4 block of pixels beyond 4.5 sigma on the two images' combined
// variance, and the whole image's mean within 1% (and within its noise).
TEST_F(Render, StridedImageAgreesWithBruteForceWithinNoise) {
  // Different seeds: the same seed would jitter both images alike, correlating them.
  const std::string common = kThick + "--spp 4096 --quiet ";
  Result brute = stf("render " + common + "--seed 5 --method brute -o " + out("b.h5"));
  ASSERT_EQ(brute.status, 0) << brute.err;
  for (const fs::path& strides : {pack(), lifted_pack()}) {
    SCOPED_TRACE(strides.string());
    expect_agreement(strides, common);
  }
}

void Render::expect_agreement(const fs::path& strides, const std::string& common) {
  Result strided = stf("render " + common + "--seed 6 --method stf --pack " + strides.string() + " -o " + out("s.h5") +
                       " --json " + out("s.json"));
  ASSERT_EQ(strided.status, 0) << strided.err;
  std::ifstream json(out("s.json"));
  std::string stats((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
  EXPECT_EQ(stats.find("\"strides\": 0,"), std::string::npos) << "no strides taken: " << stats;

  const RenderedImage b = read_image(out("b.h5"), 32, 32), s = read_image(out("s.h5"), 32, 32);
  double sum_b = 0, sum_s = 0, var = 0;
  int blocks = 0;
  for (int by = 0; by < 8; ++by)
    for (int bx = 0; bx < 8; ++bx) {
      double diff = 0, v = 0;
      for (int y = 4 * by; y < 4 * by + 4; ++y)
        for (int x = 4 * bx; x < 4 * bx + 4; ++x) {
          const std::size_t i = std::size_t(32 * y + x);
          diff += b.mean[i] - s.mean[i];
          v += b.variance_of_mean[i] + s.variance_of_mean[i];
        }
      var += v;
      if (v == 0) {  // the block sees only sky
        EXPECT_EQ(diff, 0);
        continue;
      }
      ++blocks;
      EXPECT_LT(std::abs(diff) / std::sqrt(v), 4.5) << "block " << bx << ", " << by;
    }
  EXPECT_GT(blocks, 20);
  for (std::size_t i = 0; i < b.mean.size(); ++i) sum_b += b.mean[i], sum_s += s.mean[i];
  EXPECT_NEAR(sum_s / sum_b, 1, 0.01);
  EXPECT_LT(std::abs(sum_s - sum_b) / std::sqrt(var), 4.5);
}

// Too thin for the smallest sphere anywhere: the pack built through the cache is empty and
// the strided image is the brute-force one, bit for bit.
TEST_F(Render, ThinMediumGivesTheBruteForceImage) {
  const std::string medium = "--sigma-s 1.2 --sigma-a 0.3 --g 0.5 --width 24 --height 16 --spp 64 --quiet ";
  ASSERT_EQ(stf("render " + medium + "--method brute -o " + out("b.h5")).status, 0);
  Result r = stf("render " + medium + "--method stf --cache " + out("cache") + " -o " + out("s.h5") + " --json " +
                 out("s.json"));
  ASSERT_EQ(r.status, 0) << r.err;
  const RenderedImage b = read_image(out("b.h5"), 16, 24), s = read_image(out("s.h5"), 16, 24);
  EXPECT_EQ(b.mean, s.mean);
  EXPECT_EQ(b.variance_of_mean, s.variance_of_mean);
  std::ifstream json(out("s.json"));
  std::string stats((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
  EXPECT_NE(stats.find("\"strides\": 0,"), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"spheres\": 0"), std::string::npos) << stats;
}

// Without --pack the medium's pack is built into the cache once; the next render of the medium
// takes it from there: it walks no sphere, leaves the cache's files untouched and draws the
// same image.
TEST_F(Render, SecondRenderReusesTheCachedPack) {
  const std::string args = "render --sigma-s 4.9 --sigma-a 0.1 --g 0.5 --width 16 --height 16 --spp 8 --quiet "
                           "--method stf --tolerance 0.05 --cache " + out("cache");
  // The cache's files and when each was last written.
  const auto cache_files = [&] {
    std::map<std::string, fs::file_time_type> files;
    for (const auto& e : fs::recursive_directory_iterator(out("cache")))
      if (e.is_regular_file()) files[e.path().string()] = e.last_write_time();
    return files;
  };
  std::map<std::string, fs::file_time_type> after_first;
  for (int run = 0; run < 2; ++run) {
    const std::string n = std::to_string(run);
    Result r = stf(args + " -o " + out(n + ".h5") + " --json " + out(n + ".json"));
    ASSERT_EQ(r.status, 0) << r.err;
    std::ifstream json(out(n + ".json"));
    std::string stats((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
    EXPECT_NE(stats.find("\"spheres\": 1"), std::string::npos) << stats;  // tau 4 in a tau-5 sphere
    EXPECT_NE(stats.find("\"spheres_computed\": " + std::to_string(1 - run)), std::string::npos) << stats;
    if (run == 0) after_first = cache_files();
  }
  EXPECT_FALSE(after_first.empty());                // the first render filled the cache
  EXPECT_EQ(cache_files(), after_first);            // the second wrote nothing there
  EXPECT_EQ(read_image(out("0.h5"), 16, 16).mean, read_image(out("1.h5"), 16, 16).mean);
}

TEST_F(Render, SameSeedSameImageForOneAndThreeThreads) {
  for (const std::string& method : std::vector<std::string>{"brute", "stf --pack " + pack().string()}) {
    const std::string common = kThick + "--spp 32 --seed 9 --quiet --method " + method;
    ASSERT_EQ(stf("render " + common + " --threads 1 -o " + out("1.h5")).status, 0);
    ASSERT_EQ(stf("render " + common + " --threads 3 -o " + out("3.h5")).status, 0);
    const RenderedImage one = read_image(out("1.h5"), 32, 32), three = read_image(out("3.h5"), 32, 32);
    EXPECT_EQ(one.mean, three.mean) << method;
    EXPECT_EQ(one.variance_of_mean, three.variance_of_mean) << method;
    fs::remove(out("1.h5")), fs::remove(out("3.h5"));
  }
}

// The image layout of docs/formats.md, an OpenEXR file and a PNG of the stated size.
TEST_F(Render, WritesTheContractLayoutAndImages) {
  Result r = stf("render --sigma-s 7.92 --sigma-a 0.08 --g 0.5 --width 32 --height 20 --spp 4 --seed 3 --method brute "
                 "--quiet -o " + out("i.h5") +
                 " --png " + out("i.png") + " --exr " + out("i.exr") + " --exposure -1");
  ASSERT_EQ(r.status, 0) << r.err;
  std::ifstream exr(out("i.exr"), std::ios::binary);
  char magic[4] = {};
  exr.read(magic, 4);
  EXPECT_EQ(std::string(magic, 4), std::string("\x76\x2f\x31\x01", 4));  // OpenEXR
  H5::H5File f(out("i.h5"), H5F_ACC_RDONLY);
  EXPECT_EQ(stf::h5::dataset_shape(f, "/image/mean"), (std::vector<hsize_t>{20, 32}));
  EXPECT_EQ(stf::h5::dataset_shape(f, "/image/variance_of_mean"), (std::vector<hsize_t>{20, 32}));
  EXPECT_EQ(stf::h5::get_double(f, "spp"), 4);
  EXPECT_EQ(stf::h5::get_double(f, "seed"), 3);
  EXPECT_EQ(stf::h5::get_double(f, "sigma_s"), 7.92);
  EXPECT_EQ(stf::h5::get_double(f, "radius"), 1);
  EXPECT_GT(stf::h5::get_double(f, "seconds"), 0);
  std::ifstream png(out("i.png"), std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(png)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 33u);
  EXPECT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  EXPECT_EQ(bytes.substr(12, 4), "IHDR");
  auto be32 = [&](std::size_t at) {
    return (unsigned(std::uint8_t(bytes[at])) << 24) | (unsigned(std::uint8_t(bytes[at + 1])) << 16) |
           (unsigned(std::uint8_t(bytes[at + 2])) << 8) | unsigned(std::uint8_t(bytes[at + 3]));
  };
  EXPECT_EQ(be32(16), 32u);
  EXPECT_EQ(be32(20), 20u);
  EXPECT_EQ(bytes.substr(bytes.size() - 8, 4), "IEND");
}

TEST_F(Render, BadInputIsOneLineAndNoFile) {
  const std::string ok = "render --sigma-s 2 --sigma-a 0.1 --g 0.3 --spp 4 ";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"render --sigma-s -1 --sigma-a 0.1 --g 0.3 --spp 4 --method brute", "sigma"},
      {"render --sigma-s 2 --sigma-a 0.1 --g 1.5 --spp 4 --method brute", "g"},
      {ok + "--method brute --radius 0", "radius"},
      {ok + "--method brute --width 0", "width"},
      {ok + "--method brute --height 100000", "height"},
      {"render --sigma-s 2 --sigma-a 0.1 --g 0.3 --spp 0 --method brute", "spp"},
      {ok + "--method walk", "method"},
      {ok + "--method brute --pack " + pack().string(), "--pack"},
      {ok + "--method brute --tolerance 0.05", "--tolerance"},
      {ok + "--method stf --pack " + pack().string() + " --tolerance 0.05", "--tolerance"},
      {ok + "--method stf --pack " + out("missing.stfpack"), "missing.stfpack"},
      {ok + "--method stf --tolerance -1", "tolerance"},
      {ok + "--method brute --threads -2", "threads"},
      {ok + "--method brute --exposure nan", "--exposure"},
      {ok + "--method brute --exposure 99", "--exposure"},
      {ok + "--method brute --exr /nonexistent-folder/i.exr", "--exr"},
      {ok + "--method stf --model lobes:3", "--model"},
      {ok + "--method brute --model lvmf:auto", "--model"},
      {ok + "--method stf --pack " + pack().string() + " --model lvmf:auto", "--model"},
  };
  for (const auto& [args, names] : cases) {
    expect_one_line(stf(args + " -o " + out("i.h5") + " --png " + out("i.png")), names, args);
    EXPECT_FALSE(fs::exists(out("i.h5"))) << args;
    EXPECT_FALSE(fs::exists(out("i.png"))) << args;
    EXPECT_FALSE(fs::exists(out("i.exr"))) << args;
  }
  // A pack without this medium is refused, not rendered without strides.
  expect_one_line(stf("render --sigma-s 2 --sigma-a 0.1 --g 0.3 --spp 4 --method stf --pack " + pack().string() +
                      " -o " + out("i.h5")),
                  "pack", "foreign pack");
  EXPECT_FALSE(fs::exists(out("i.h5")));
}

// Images go through a module loaded on first use (render/image_codec.h); where it cannot be
// loaded, one line says which and why, and nothing is written.
TEST_F(Render, AMissingImageCodecIsOneLineAndNoFile) {
  ::setenv("STF_IMAGE_CODEC", out("missing/libstf_image_codec.so").c_str(), 1);
  const Result r = stf("render --sigma-s 2 --sigma-a 0.1 --g 0.3 --spp 4 --method brute -o " + out("i.h5") + " --png " +
                       out("i.png"));
  ::unsetenv("STF_IMAGE_CODEC");
  expect_one_line(r, "libstf_image_codec.so", "no image codec");
  EXPECT_FALSE(fs::exists(out("i.h5")));
  EXPECT_FALSE(fs::exists(out("i.png")));
}

}  // namespace
