// The procedural cumulus (stf/media/cloud.h) and grid files written from values
// (stf/media/grid_file.h): determinism, the exact core and empty outer layer the cloud promises,
// and one density field read back from its .vdb and its .npy. Randomised points take their seed
// from $STF_TEST_SEED and print it.
#include "stf/media/cloud.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <stdexcept>
#include <string>

#include "stf/media/density_grid.h"
#include "stf/media/grid_file.h"

namespace {

namespace fs = std::filesystem;
using stf::Vec3;
using stf::media::Box;
using stf::media::Cumulus;
using stf::media::cumulus;
using stf::media::DensityGrid;

constexpr int kSize = 32;

std::uint64_t test_seed() {
  const char* given = std::getenv("STF_TEST_SEED");
  return given ? std::strtoull(given, nullptr, 10) : 20240611;
}

float at(const Cumulus& c, int i, int j, int k) {
  return c.values[(std::size_t(i) * std::size_t(c.size) + std::size_t(j)) * std::size_t(c.size) +
                  std::size_t(k)];
}

class CloudFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("stf_cloud_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string file(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};

TEST(Cloud, SameSeedSameCloudOnAnyThreadsOtherSeedAnother) {
  const Cumulus a = cumulus(kSize, 1, stf::RunContext{1, nullptr, {}});
  EXPECT_EQ(a.values, cumulus(kSize, 1, stf::RunContext{3, nullptr, {}}).values);
  EXPECT_NE(a.values, cumulus(kSize, 2).values);
  EXPECT_EQ(a.size, kSize);
  ASSERT_EQ(a.values.size(), std::size_t(kSize) * kSize * kSize);
}

// One continuous field at every size: the centres of 16^3 voxels are centres of 48^3 ones
// ((i + 1/2) / 16 = (3 i + 3/2) / 48, both exact in binary).
TEST(Cloud, OneFieldAtEverySize) {
  const Cumulus coarse = cumulus(16, 5), fine = cumulus(48, 5);
  for (int i = 0; i < 16; ++i)
    for (int j = 0; j < 16; ++j)
      for (int k = 0; k < 16; ++k)
        ASSERT_EQ(at(coarse, i, j, k), at(fine, 3 * i + 1, 3 * j + 1, 3 * k + 1))
            << i << " " << j << " " << k;
}

// Values in [0, 1]; exactly 1 over a substantial core; 0 on the outermost layer, for several seeds.
TEST(Cloud, ExactCoreInUnitIntervalEmptyOuterLayer) {
  for (std::uint64_t seed : {0ull, 1ull, 2ull, 77ull, 123456789ull}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Cumulus c = cumulus(kSize, seed);
    std::size_t non_zero = 0, full = 0;
    for (const float v : c.values) {
      ASSERT_GE(v, 0.0f);
      ASSERT_LE(v, 1.0f);
      non_zero += v > 0;
      full += v == 1.0f;
    }
    EXPECT_GT(full, 0u);
    EXPECT_GT(double(full), 0.15 * double(non_zero)) << full << " of " << non_zero;
    EXPECT_LT(double(full), 0.5 * double(non_zero)) << full << " of " << non_zero;
    for (int i = 0; i < kSize; ++i)
      for (int j = 0; j < kSize; ++j) {
        const int e = kSize - 1;
        for (const float v : {at(c, 0, i, j), at(c, e, i, j), at(c, i, 0, j), at(c, i, e, j),
                              at(c, i, j, 0), at(c, i, j, e)})
          ASSERT_EQ(v, 0.0f) << i << " " << j;
      }
  }
}

TEST(Cloud, SizeOutOfRangeIsRefused) {
  EXPECT_THROW(cumulus(stf::media::kMinCloudSize - 1, 1), std::invalid_argument);
  EXPECT_THROW(cumulus(stf::media::kMaxCloudSize + 1, 1), std::invalid_argument);
}

// The .vdb and the .npy of one cloud, read back, give one density field, inside the cube and
// past it (the outer layer is 0, so neither reaches past the bounds), and it is the field of the
// values themselves.
TEST_F(CloudFiles, VdbAndNpyOfTheCloudAgree) {
  const Cumulus c = cumulus(kSize, 3);
  stf::media::write_grid(file("cloud.vdb"), c.values, c.size, c.bounds);
  stf::media::write_grid(file("cloud.npy"), c.values, c.size, c.bounds);
  const DensityGrid vdb = DensityGrid::read(file("cloud.vdb"), std::nullopt);
  const DensityGrid npy = DensityGrid::read(file("cloud.npy"), c.bounds);
  const DensityGrid values = DensityGrid::from_values(c.values, c.size, c.size, c.size, c.bounds);
  EXPECT_EQ(vdb.max_density(), 1.0);
  std::mt19937_64 rng(test_seed());
  SCOPED_TRACE("STF_TEST_SEED=" + std::to_string(test_seed()));
  std::uniform_real_distribution<double> x(-0.55, 0.55);
  int inside = 0;
  for (int m = 0; m < 1000; ++m) {
    const Vec3 p{x(rng), x(rng), x(rng)};
    const double expected = values.density(p);
    inside += expected > 0;
    EXPECT_NEAR(vdb.density(p), expected, 1e-6) << p.x << " " << p.y << " " << p.z;
    EXPECT_NEAR(npy.density(p), expected, 1e-6) << p.x << " " << p.y << " " << p.z;
  }
  EXPECT_GT(inside, 50);  // the points do meet the cloud
}

// Voxel centres land on lattice points: the files give back the values themselves there.
TEST_F(CloudFiles, VoxelCentresGiveTheValues) {
  const Cumulus c = cumulus(kSize, 4);
  stf::media::write_grid(file("c.vdb"), c.values, c.size, c.bounds);
  const DensityGrid vdb = DensityGrid::read(file("c.vdb"), std::nullopt);
  const auto centre = [](int i) { return -0.5 + (i + 0.5) / kSize; };
  for (int i = 0; i < kSize; i += 3)
    for (int j = 0; j < kSize; j += 2)
      for (int k = 0; k < kSize; ++k)
        ASSERT_NEAR(vdb.density({centre(i), centre(j), centre(k)}), at(c, i, j, k), 1e-6)
            << i << " " << j << " " << k;
}

TEST_F(CloudFiles, RefusedGridsWriteNothing) {
  const Cumulus c = cumulus(16, 1);
  EXPECT_THROW(stf::media::write_grid(file("c.raw"), c.values, c.size, c.bounds),
               std::invalid_argument);
  EXPECT_THROW(stf::media::write_grid(file("c.npy"), c.values, c.size + 1, c.bounds),
               std::invalid_argument);
  std::vector<float> negative = c.values;
  negative[5] = -1;
  EXPECT_THROW(stf::media::write_grid(file("c.vdb"), negative, c.size, c.bounds),
               std::invalid_argument);
  EXPECT_THROW(stf::media::write_grid(file("c.npy"), std::vector<float>(c.values.size(), 0.0f),
                                      c.size, c.bounds),
               std::invalid_argument);
  EXPECT_FALSE(fs::exists(file("c.vdb")) || fs::exists(file("c.npy")) || fs::exists(file("c.raw")));
  try {
    stf::media::write_grid((dir_ / "no" / "such" / "c.npy").string(), c.values, c.size, c.bounds);
    ADD_FAILURE() << "written into a missing folder";
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    EXPECT_NE(message.find("cannot write"), std::string::npos) << message;
  }
}

}  // namespace
