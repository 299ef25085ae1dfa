// Density grids: the .npy and .vdb conventions (files written here, .npy by hand bytes, .vdb with
// OpenVDB), the majorant bricks, delta and ratio tracking against exact optical depths, and every
// refused grid in one line. Randomised tests take their seed from $STF_TEST_SEED and print it.
#include <gtest/gtest.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "chi2.h"
#include "stf/media/density_grid.h"
#include "stf/media/stride_rooms.h"
#include "stf/media/tracking.h"

namespace {

namespace fs = std::filesystem;
using stf::Vec3;
using stf::dot;
using stf::length;
using stf::normalize;
using stf::media::Box;
using stf::media::DensityGrid;
using stf::media::StrideRooms;
using stf::media::stride_rooms;

std::uint64_t test_seed() {
  const char* given = std::getenv("STF_TEST_SEED");
  return given ? std::strtoull(given, nullptr, 10) : 20240611;
}

double axis(const Vec3& v, int a) { return a == 0 ? v.x : a == 1 ? v.y : v.z; }

// ---- files -------------------------------------------------------------------------------

std::string npy_dict(const std::string& descr, const std::string& shape, bool fortran = false) {
  return "{'descr': '" + descr + "', 'fortran_order': " + (fortran ? "True" : "False") + ", 'shape': " + shape + ", }";
}

// An .npy file's bytes as numpy writes them: magic, version, little-endian header length, the
// dict padded with spaces to a multiple of 64 bytes and ended by a newline, then the data.
std::string npy_bytes(const std::string& dict, int major, const std::string& data) {
  std::string header = dict;
  const std::size_t prefix = 8 + (major == 1 ? 2 : 4);
  while ((prefix + header.size() + 1) % 64 != 0) header += ' ';
  header += '\n';
  std::string out = "\x93NUMPY";
  out += char(major), out += char(0);
  for (int b = 0; b < (major == 1 ? 2 : 4); ++b) out += char((header.size() >> (8 * b)) & 0xff);
  return out + header + data;
}

template <class T>
std::string raw(const std::vector<double>& values) {
  std::string data(values.size() * sizeof(T), '\0');
  for (std::size_t i = 0; i < values.size(); ++i) {
    const T v = T(values[i]);
    std::memcpy(&data[i * sizeof(T)], &v, sizeof(T));
  }
  return data;
}

void write_file(const fs::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

void write_npy(const fs::path& path, const std::vector<double>& values, int nx, int ny, int nz, bool f8 = false,
               int major = 1) {
  const std::string shape = "(" + std::to_string(nx) + ", " + std::to_string(ny) + ", " + std::to_string(nz) + ")";
  write_file(path, npy_bytes(npy_dict(f8 ? "<f8" : "<f4", shape), major, f8 ? raw<double>(values) : raw<float>(values)));
}

openvdb::FloatGrid::Ptr vdb_grid(const std::string& name, openvdb::math::Transform::Ptr transform, float background = 0) {
  openvdb::initialize();
  auto grid = openvdb::FloatGrid::create(background);
  grid->setName(name);
  grid->setTransform(transform);
  return grid;
}

void write_vdb(const fs::path& path, const openvdb::GridPtrVec& grids) {
  openvdb::io::File file(path.string());
  file.write(grids);
  file.close();
}

// A field with structure at every scale of the lattice, zero in a slab (whole empty bricks:
// lattice points 7 to 23 along x when nx >= 24) and in scattered voxels.
std::vector<float> cloud_values(int nx, int ny, int nz) {
  std::vector<float> v(std::size_t(nx) * std::size_t(ny) * std::size_t(nz));
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j)
      for (int k = 0; k < nz; ++k) {
        double d = 1.2 + std::sin(0.7 * i) * std::cos(0.45 * j) + 0.8 * std::sin(0.3 * k + 1) + 0.1 * ((i * 7 + j * 3 + k) % 5);
        if (i >= 6 && i < 24) d = 0;  // an empty slab
        v[(std::size_t(i) * std::size_t(ny) + std::size_t(j)) * std::size_t(nz) + std::size_t(k)] = float(std::max(0.0, d));
      }
  return v;
}

class Media : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("stf_media_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string file(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};


// The one-line refusal of `read`: it names `path` first and says each of `words`.
void expect_refusal(const std::function<void()>& read, const std::string& path, const std::vector<std::string>& words) {
  try {
    read();
    ADD_FAILURE() << path << " was read";
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    EXPECT_EQ(message.rfind(path + ": ", 0), 0u) << message;
    for (const std::string& word : words) EXPECT_NE(message.find(word), std::string::npos) << message << " lacks " << word;
  }
}

// ---- the grid codec module -----------------------------------------------------------------

// First in the file: the module is loaded once per process (ctest runs each test on its own).
TEST_F(Media, AMissingGridCodecIsOneLine) {
  auto grid = vdb_grid("density", openvdb::math::Transform::createLinearTransform(1.0));
  grid->tree().setValue(openvdb::Coord(0, 0, 0), 1.0f);
  write_vdb(file("g.vdb"), {grid});
  ::setenv("STF_GRID_CODEC", file("missing/libstf_grid_codec.so").c_str(), 1);
  try {
    DensityGrid::read(file("g.vdb"), std::nullopt);
    ADD_FAILURE() << "read without its codec";
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("libstf_grid_codec.so"), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
  ::unsetenv("STF_GRID_CODEC");
  EXPECT_DOUBLE_EQ(DensityGrid::read(file("g.vdb"), std::nullopt).density({0, 0, 0}), 1.0);  // tried again
}

// ---- .npy conventions ----------------------------------------------------------------------

constexpr int kNx = 3, kNy = 4, kNz = 5;
const Box kBounds{{-1, 0, 2}, {2, 4, 7}};  // voxels 1 x 1 x 1

std::vector<double> small_values() {
  std::vector<double> v(kNx * kNy * kNz);
  for (std::size_t n = 0; n < v.size(); ++n) v[n] = 0.5 + double((n * 37) % 23);
  return v;
}
double small_value(int i, int j, int k) { return small_values()[std::size_t((i * kNy + j) * kNz + k)]; }
Vec3 centre(int i, int j, int k) { return {-1 + i + 0.5, 0 + j + 0.5, 2 + k + 0.5}; }

TEST_F(Media, NpyValuesSitAtVoxelCentres) {
  write_npy(file("a.npy"), small_values(), kNx, kNy, kNz);
  const DensityGrid grid = DensityGrid::read(file("a.npy"), kBounds);
  for (int i = 0; i < kNx; ++i)
    for (int j = 0; j < kNy; ++j)
      for (int k = 0; k < kNz; ++k) EXPECT_NEAR(grid.density(centre(i, j, k)), small_value(i, j, k), 1e-12);
}

TEST_F(Media, NpyIsTrilinearBetweenCentres) {
  write_npy(file("a.npy"), small_values(), kNx, kNy, kNz);
  const DensityGrid grid = DensityGrid::read(file("a.npy"), kBounds);
  const double fx = 0.25, fy = 0.5, fz = 0.875;  // from centre (1, 2, 3) towards (2, 3, 4)
  double expected = 0;
  for (int c = 0; c < 8; ++c) {
    const int di = c >> 2, dj = (c >> 1) & 1, dk = c & 1;
    expected += (di ? fx : 1 - fx) * (dj ? fy : 1 - fy) * (dk ? fz : 1 - fz) * small_value(1 + di, 2 + dj, 3 + dk);
  }
  EXPECT_NEAR(grid.density(centre(1, 2, 3) + Vec3{fx, fy, fz}), expected, 1e-12);
}

// Past the outer centres the field falls towards the padding's zeros, and at the bounds it stops.
TEST_F(Media, NpyRampsToZeroPaddingAndStopsAtTheBounds) {
  write_npy(file("a.npy"), small_values(), kNx, kNy, kNz);
  const DensityGrid grid = DensityGrid::read(file("a.npy"), kBounds);
  const double v = small_value(0, 1, 2), w = small_value(2, 1, 2);
  EXPECT_NEAR(grid.density(centre(0, 1, 2) - Vec3{0.25, 0, 0}), 0.75 * v, 1e-12);
  EXPECT_NEAR(grid.density(centre(0, 1, 2) - Vec3{0.4999, 0, 0}), 0.5001 * v, 1e-12);
  EXPECT_NEAR(grid.density(centre(2, 1, 2) + Vec3{0.375, 0, 0}), 0.625 * w, 1e-12);
  EXPECT_EQ(grid.density(centre(0, 1, 2) - Vec3{0.5001, 0, 0}), 0.0);  // past x0: clipped
  EXPECT_EQ(grid.density(centre(2, 1, 2) + Vec3{0.5001, 0, 0}), 0.0);
  EXPECT_EQ(grid.density({100, 2, 4}), 0.0);
  EXPECT_EQ(grid.density({0, 2, -100}), 0.0);
  const Box support = grid.support();  // every voxel is non-zero: the support is the bounds
  EXPECT_NEAR(support.lower.x, -1, 1e-12);
  EXPECT_NEAR(support.upper.z, 7, 1e-12);
  // The least of the field is at a corner of the bounds: an eighth of the corner voxel's value.
  EXPECT_NEAR(grid.min_density(), std::min({small_value(0, 0, 0), small_value(0, 0, kNz - 1), small_value(0, kNy - 1, 0),
                                            small_value(0, kNy - 1, kNz - 1), small_value(kNx - 1, 0, 0),
                                            small_value(kNx - 1, 0, kNz - 1), small_value(kNx - 1, kNy - 1, 0),
                                            small_value(kNx - 1, kNy - 1, kNz - 1)}) /
                                  8,
              1e-12);
  const std::vector<double> values = small_values();
  EXPECT_DOUBLE_EQ(grid.max_density(), *std::max_element(values.begin(), values.end()));
}

// float32 and float64 data, headers of versions 1.0, 2.0 and 3.0: the same field.
TEST_F(Media, NpyDtypesAndHeaderVersionsReadAlike) {
  write_npy(file("v1.npy"), small_values(), kNx, kNy, kNz, false, 1);
  write_npy(file("v2.npy"), small_values(), kNx, kNy, kNz, true, 2);
  write_npy(file("v3.npy"), small_values(), kNx, kNy, kNz, true, 3);
  const DensityGrid a = DensityGrid::read(file("v1.npy"), kBounds), b = DensityGrid::read(file("v2.npy"), kBounds),
                    c = DensityGrid::read(file("v3.npy"), kBounds);
  std::mt19937_64 rng(test_seed());
  SCOPED_TRACE("STF_TEST_SEED=" + std::to_string(test_seed()));
  std::uniform_real_distribution<double> x(-1.2, 2.2), y(-0.2, 4.2), z(1.8, 7.2);
  for (int n = 0; n < 200; ++n) {
    const Vec3 p{x(rng), y(rng), z(rng)};
    EXPECT_EQ(a.density(p), b.density(p));
    EXPECT_EQ(a.density(p), c.density(p));
  }
  const std::vector<double> values = small_values();
  const DensityGrid d = DensityGrid::from_values(std::vector<float>(values.begin(), values.end()), kNx, kNy, kNz, kBounds);
  EXPECT_EQ(a.density({0.3, 1.7, 4.1}), d.density({0.3, 1.7, 4.1}));
}

// ---- .vdb conventions ----------------------------------------------------------------------

using openvdb::Coord;
using openvdb::Vec3d;

Vec3 to_vec3(const Vec3d& v) { return {v.x(), v.y(), v.z()}; }

float index_value(const Coord& c) { return float(1 + ((c.x() * 5 + c.y() * 3 + c.z() * 7) % 11 + 11) % 11); }

TEST_F(Media, VdbValuesSitAtIndexCoordinates) {
  auto transform = openvdb::math::Transform::createLinearTransform(1.0);
  transform->preScale(Vec3d(0.5, 0.25, 2));
  transform->postTranslate(Vec3d(1, -2, 3));
  auto grid = vdb_grid("density", transform, 5.0f);  // a background that is not density
  for (int x = 2; x <= 6; ++x)
    for (int y = -3; y <= 1; ++y)
      for (int z = 10; z <= 12; ++z) grid->tree().setValue(Coord(x, y, z), index_value(Coord(x, y, z)));
  grid->tree().setValueOff(Coord(4, -1, 11), 9.0f);  // inactive: 0 whatever it holds
  write_vdb(file("g.vdb"), {grid});
  const DensityGrid density = DensityGrid::read(file("g.vdb"), std::nullopt);
  for (int x = 2; x <= 6; ++x)
    for (int y = -3; y <= 1; ++y)
      for (int z = 10; z <= 12; ++z) {
        const Coord c(x, y, z);
        const double expected = c == Coord(4, -1, 11) ? 0 : index_value(c);
        EXPECT_NEAR(density.density(to_vec3(transform->indexToWorld(c))), expected, 1e-5) << c;
      }
  EXPECT_EQ(density.density(to_vec3(transform->indexToWorld(Vec3d(2, -3, 8.5)))), 0.0);   // past the ramp
  EXPECT_NEAR(density.density(to_vec3(transform->indexToWorld(Vec3d(2, -3, 9.5)))), 0.5 * index_value(Coord(2, -3, 10)), 1e-5);
  const Box support = density.support();  // the active box, one voxel wider
  EXPECT_NEAR(support.lower.x, 1 + 0.5 * 1, 1e-12);
  EXPECT_NEAR(support.upper.z, 3 + 2 * 13, 1e-12);
}

// An affine map (turned, sheared by unequal scales, moved) and a tile of active voxels.
openvdb::FloatGrid::Ptr affine_grid(std::mt19937_64& rng) {
  auto transform = openvdb::math::Transform::createLinearTransform(1.0);
  transform->preScale(Vec3d(0.3, 0.5, 0.4));
  transform->postRotate(0.4, openvdb::math::Z_AXIS);
  transform->postRotate(-0.7, openvdb::math::X_AXIS);
  transform->postTranslate(Vec3d(-1, 2, 0.5));
  auto grid = vdb_grid("smoke", transform);
  std::uniform_real_distribution<double> value(0, 3), coin(0, 1);
  for (int x = -4; x < 10; ++x)
    for (int y = 0; y < 12; ++y)
      for (int z = 3; z < 13; ++z)
        if (coin(rng) < 0.8) grid->tree().setValue(Coord(x, y, z), float(value(rng)));
  grid->tree().addTile(1, Coord(16, 0, 8), 1.5f, true);  // 8^3 voxels in one value
  return grid;
}

TEST_F(Media, VdbIsTrilinearAsBoxSampler) {
  std::mt19937_64 rng(test_seed());
  SCOPED_TRACE("STF_TEST_SEED=" + std::to_string(test_seed()));
  const auto grid = affine_grid(rng);
  write_vdb(file("g.vdb"), {grid});
  const DensityGrid density = DensityGrid::read(file("g.vdb"), std::nullopt);
  openvdb::tools::GridSampler<openvdb::FloatGrid, openvdb::tools::BoxSampler> sampler(*grid);
  std::uniform_real_distribution<double> x(-6, 26), y(-2, 14), z(1, 18);
  for (int n = 0; n < 1000; ++n) {
    const Vec3d world = grid->transform().indexToWorld(Vec3d(x(rng), y(rng), z(rng)));
    const double expected = sampler.wsSample(world);
    EXPECT_NEAR(density.density(to_vec3(world)), expected, 1e-5 * std::max(1.0, expected)) << world;
  }
}

// The same field as a .vdb (voxel size 0.25, index (i, j, k) at the voxel centres) and an .npy
// in bounds: one density within the bounds, to float rounding.
TEST_F(Media, VdbAndNpyOfOneFieldAgree) {
  const int n[3] = {10, 7, 9};
  const Box bounds{{0.5, -1, 2}, {3, 0.75, 4.25}};
  auto transform = openvdb::math::Transform::createLinearTransform(0.25);
  transform->postTranslate(Vec3d(0.5 + 0.125, -1 + 0.125, 2 + 0.125));
  auto grid = vdb_grid("density", transform);
  std::vector<double> values;
  for (int i = 0; i < n[0]; ++i)
    for (int j = 0; j < n[1]; ++j)
      for (int k = 0; k < n[2]; ++k) {
        values.push_back(0.25 + index_value(Coord(i, j, k)) / 3.0);
        grid->tree().setValue(Coord(i, j, k), float(values.back()));
      }
  write_vdb(file("g.vdb"), {grid});
  write_npy(file("g.npy"), values, n[0], n[1], n[2]);
  const DensityGrid a = DensityGrid::read(file("g.vdb"), std::nullopt), b = DensityGrid::read(file("g.npy"), bounds);
  std::mt19937_64 rng(test_seed());
  SCOPED_TRACE("STF_TEST_SEED=" + std::to_string(test_seed()));
  std::uniform_real_distribution<double> x(0.5, 3), y(-1, 0.75), z(2, 4.25);
  for (int m = 0; m < 1000; ++m) {
    const Vec3 p{x(rng), y(rng), z(rng)};
    EXPECT_NEAR(a.density(p), b.density(p), 1e-6 * std::max(1.0, b.density(p))) << p.x << " " << p.y << " " << p.z;
  }
}

// ---- the majorant bricks -------------------------------------------------------------------

// Rounding: the field is a convex combination of float values computed in double.
double slack(double v) { return 1e-12 * std::max(1.0, std::abs(v)); }

const Box kCloudBounds{{0, 0, 0}, {3, 2, 2.5}};  // voxels of 0.1
DensityGrid cloud_grid() { return DensityGrid::from_values(cloud_values(30, 20, 25), 30, 20, 25, kCloudBounds); }

DensityGrid affine_vdb(const std::string& path) {
  std::mt19937_64 rng(7);
  write_vdb(path, {affine_grid(rng)});
  return DensityGrid::read(path, std::nullopt);
}

// A brick's min and max are exactly those of the lattice values at its cells' corners (the
// padding's zeros included): the field's own extremes over it.
void expect_brick_is_its_corners(const DensityGrid& grid, int bx, int by, int bz) {
  double least = INFINITY, most = -INFINITY;
  for (int i = 0; i <= DensityGrid::kBrick; ++i)
    for (int j = 0; j <= DensityGrid::kBrick; ++j)
      for (int k = 0; k <= DensityGrid::kBrick; ++k) {
        const Vec3 u{DensityGrid::brick_lower(bx) + i, DensityGrid::brick_lower(by) + j, DensityGrid::brick_lower(bz) + k};
        const double v = grid.lattice_density(u);  // the value there, 0 on and past the padding
        least = std::min(least, v), most = std::max(most, v);
      }
  EXPECT_EQ(grid.brick(bx, by, bz).min, least) << bx << " " << by << " " << bz;
  EXPECT_EQ(grid.brick(bx, by, bz).max, most) << bx << " " << by << " " << bz;
}

// Random lattice points of every brick lie within its [min, max].
void expect_bricks_bound_the_field(const DensityGrid& grid, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> offset(0, DensityGrid::kBrick);
  const auto& counts = grid.brick_counts();
  int empty = 0;
  for (int bx = 0; bx < counts[0]; ++bx)
    for (int by = 0; by < counts[1]; ++by)
      for (int bz = 0; bz < counts[2]; ++bz) {
        const DensityGrid::Brick& brick = grid.brick(bx, by, bz);
        empty += brick.max == 0;
        expect_brick_is_its_corners(grid, bx, by, bz);
        for (int n = 0; n < 60; ++n) {
          const Vec3 u{DensityGrid::brick_lower(bx) + offset(rng), DensityGrid::brick_lower(by) + offset(rng),
                       DensityGrid::brick_lower(bz) + offset(rng)};
          const double v = grid.lattice_density(u);
          ASSERT_GE(v, brick.min - slack(v)) << bx << " " << by << " " << bz;
          ASSERT_LE(v, brick.max + slack(v)) << bx << " " << by << " " << bz;
        }
      }
  ::testing::Test::RecordProperty("empty_bricks", empty);
}

// A block's room, against the cube of blocks about it read directly: the largest k whose cube
// (inside the grid) keeps the tolerance, -1 where not even the block does; and random points of
// that cube's region hold densities within the cube's range, so within the tolerance.
void expect_rooms_are_their_cubes(const DensityGrid& grid, double tolerance, std::mt19937_64& rng) {
  std::array<int, 3> n{};
  const std::vector<DensityGrid::Brick> blocks = grid.block_ranges(StrideRooms::kBlock, n);
  const StrideRooms rooms = stride_rooms(grid, tolerance);
  ASSERT_EQ(rooms.counts, n);
  const auto cube = [&](int x, int y, int z, int k) {
    DensityGrid::Brick r{INFINITY, 0};
    for (int i = x - k; i <= x + k; ++i)
      for (int j = y - k; j <= y + k; ++j)
        for (int l = z - k; l <= z + k; ++l) {
          const bool inside = i >= 0 && j >= 0 && l >= 0 && i < n[0] && j < n[1] && l < n[2];
          const DensityGrid::Brick b = inside ? blocks[(std::size_t(i) * std::size_t(n[1]) + std::size_t(j)) * std::size_t(n[2]) + std::size_t(l)] : DensityGrid::Brick{};
          r.min = std::min(r.min, b.min), r.max = std::max(r.max, b.max);
        }
    return r;
  };
  const auto keeps = [&](const DensityGrid::Brick& r) { return r.min > 0 && r.max <= (1 + tolerance) * r.min; };
  std::uniform_int_distribution<int> bx(0, n[0] - 1), by(0, n[1] - 1), bz(0, n[2] - 1);
  std::uniform_real_distribution<double> unit(0, 1);
  int kept = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const int x = bx(rng), y = by(rng), z = bz(rng), k = rooms.at(x, y, z);
    if (k < 0) {
      EXPECT_FALSE(keeps(cube(x, y, z, 0))) << x << " " << y << " " << z;
      continue;
    }
    ++kept;
    const DensityGrid::Brick r = cube(x, y, z, k);
    ASSERT_TRUE(keeps(r)) << x << " " << y << " " << z << " room " << k;
    EXPECT_FALSE(keeps(cube(x, y, z, k + 1))) << x << " " << y << " " << z << " room " << k;
    for (int m = 0; m < 40; ++m) {
      const double side = (2 * k + 1) * StrideRooms::kBlock;
      const Vec3 u{StrideRooms::block_lower(x - k) + side * unit(rng), StrideRooms::block_lower(y - k) + side * unit(rng),
                   StrideRooms::block_lower(z - k) + side * unit(rng)};
      const double v = grid.lattice_density(u);
      ASSERT_GE(v, r.min - slack(v));
      ASSERT_LE(v, r.max + slack(v));
    }
  }
  ::testing::Test::RecordProperty("kept_" + std::to_string(tolerance), kept);
}

TEST_F(Media, BricksAndStrideRoomsBoundTheField) {
  std::mt19937_64 rng(test_seed());
  SCOPED_TRACE("STF_TEST_SEED=" + std::to_string(test_seed()));
  const DensityGrid cloud = cloud_grid(), affine = affine_vdb(file("g.vdb"));
  for (const DensityGrid* grid : {&cloud, &affine}) {
    expect_bricks_bound_the_field(*grid, rng);
    for (double tolerance : {0.0, 0.3, 1.0}) expect_rooms_are_their_cubes(*grid, tolerance, rng);
  }
  // A constant grid keeps any tolerance up to the blocks that reach its zero padding: the room
  // of its centre block is the distance to them.
  const DensityGrid constant = DensityGrid::from_values(std::vector<float>(32 * 32 * 32, 2.5f), 32, 32, 32, {{0, 0, 0}, {1, 1, 1}});
  const StrideRooms rooms = stride_rooms(constant, 0);
  EXPECT_EQ(rooms.counts, (std::array<int, 3>{17, 17, 17}));
  EXPECT_EQ(rooms.at(8, 8, 8), 7);
  EXPECT_EQ(rooms.at(0, 8, 8), -1);
  EXPECT_EQ(constant.bytes(), 32u * 32 * 32 * 4 + 5 * 5 * 5 * 8);
}

// ---- tracking ------------------------------------------------------------------------------

// sigma times the integral of the density along o + s w, s in [0, t]. Between crossings of the
// lattice's planes (and the half-integer ones, where .npy bounds clip), the field is a cubic in s,
// which 3-point Gauss-Legendre integrates exactly.
double optical_depth(const DensityGrid& grid, double sigma, const Vec3& o, const Vec3& w, double t) {
  const Vec3 u = grid.to_lattice(o), d = grid.lattice_direction(w);
  std::vector<double> cuts{0, t};
  for (int a = 0; a < 3; ++a) {
    if (axis(d, a) == 0) continue;
    const double from = std::min(axis(u, a), axis(u, a) + t * axis(d, a)), to = std::max(axis(u, a), axis(u, a) + t * axis(d, a));
    for (double plane = std::ceil(2 * from) / 2; plane <= to; plane += 0.5) cuts.push_back((plane - axis(u, a)) / axis(d, a));
  }
  std::sort(cuts.begin(), cuts.end());
  const double node = std::sqrt(0.6), weights[3] = {5.0 / 9, 8.0 / 9, 5.0 / 9}, nodes[3] = {-node, 0, node};
  double tau = 0;
  for (std::size_t c = 0; c + 1 < cuts.size(); ++c) {
    const double a = std::clamp(cuts[c], 0.0, t), b = std::clamp(cuts[c + 1], 0.0, t), half = (b - a) / 2;
    for (int g = 0; g < 3; ++g) tau += half * weights[g] * grid.density(o + w * (a + half + half * nodes[g]));
  }
  return sigma * tau;
}

struct Ray {
  Vec3 o, w;
  double t_max;
};

// Rays through the cloud (into it, from inside, along an axis, across its empty slab) and through the affine grid.
std::vector<Ray> cloud_rays() {
  return {{{-0.5, 1.0, 1.2}, normalize({1, 0.1, 0.05}), 4.0},
          {{0.9, 1.0, 1.25}, normalize({-0.6, 0.6, -0.5}), 1.5},
          {{0.2, 0.3, 0.4}, normalize({1, 1, 1}), 3.5},
          {{0.55, 1.05, -1}, {0, 0, 1}, 5.0}};
}

Ray affine_ray(const openvdb::math::Transform& transform) {
  const Vec3 from = to_vec3(transform.indexToWorld(Vec3d(-6, 5, 8))), to = to_vec3(transform.indexToWorld(Vec3d(25, 6, 10)));
  return {from, normalize(to - from), length(to - from)};
}

// sigma giving the ray an optical depth of 1.5.
double sigma_for(const DensityGrid& grid, const Ray& ray) {
  const double tau = optical_depth(grid, 1, ray.o, ray.w, ray.t_max);
  EXPECT_GT(tau, 0) << "a ray through no density";
  return 1.5 / tau;
}

// Escapes match exp(-tau) within 4 binomial standard errors, and the collision distances pass a
// chi-square test against the exact distribution 1 - exp(-tau(t)).
void expect_delta_tracking_exact(const DensityGrid& grid, const Ray& ray, std::mt19937_64& rng) {
  const double sigma = sigma_for(grid, ray);
  std::uniform_real_distribution<double> uniform(0, 1);
  auto u = [&] { return uniform(rng); };
  constexpr int kFlights = 20000, kBins = 24;
  std::vector<double> observed(kBins + 1, 0), expected(kBins + 1, 0);
  for (int n = 0; n < kFlights; ++n) {
    const stf::media::Flight f = stf::media::delta_track(grid, sigma, ray.o, ray.w, ray.t_max, u);
    observed[f.collided ? std::min(kBins - 1, int(f.t / ray.t_max * kBins)) : kBins] += 1;
  }
  double before = 1;  // exp(-tau) at the bin's start
  for (int b = 0; b < kBins; ++b) {
    const double after = std::exp(-optical_depth(grid, sigma, ray.o, ray.w, ray.t_max * (b + 1) / kBins));
    expected[b] = kFlights * (before - after), before = after;
  }
  expected[kBins] = kFlights * before;
  const double escape = before, se = std::sqrt(escape * (1 - escape) / kFlights);
  EXPECT_NEAR(observed[kBins] / kFlights, escape, 4 * se);
  const stf::test::Chi2Result chi2 = stf::test::chi2_test(observed, expected);
  EXPECT_GT(chi2.p_value, stf::test::kChi2Alpha) << chi2.describe();
}

// The mean of ratio tracking matches exp(-tau) within 4 standard errors of the mean.
void expect_ratio_tracking_exact(const DensityGrid& grid, const Ray& ray, std::mt19937_64& rng) {
  const double sigma = sigma_for(grid, ray);
  std::uniform_real_distribution<double> uniform(0, 1);
  auto u = [&] { return uniform(rng); };
  constexpr int kRuns = 20000;
  double sum = 0, sum2 = 0;
  for (int n = 0; n < kRuns; ++n) {
    const double t = stf::media::ratio_track(grid, sigma, ray.o, ray.w, ray.t_max, u).transmittance;
    sum += t, sum2 += t * t;
  }
  const double mean = sum / kRuns, variance = (sum2 - sum * mean) / (kRuns - 1);
  EXPECT_NEAR(mean, std::exp(-optical_depth(grid, sigma, ray.o, ray.w, ray.t_max)),
              4 * std::sqrt(std::max(variance, 0.0) / kRuns) + 1e-12);
}

TEST_F(Media, DeltaTrackingFollowsTheExactFreeFlightDistribution) {
  std::mt19937_64 rng(test_seed());
  SCOPED_TRACE("STF_TEST_SEED=" + std::to_string(test_seed()));
  const DensityGrid cloud = cloud_grid();
  for (const Ray& ray : cloud_rays()) {
    SCOPED_TRACE("cloud ray from " + std::to_string(ray.o.x) + ", " + std::to_string(ray.o.y) + ", " + std::to_string(ray.o.z));
    expect_delta_tracking_exact(cloud, ray, rng);
  }
  std::mt19937_64 make(7);
  const auto vdb = affine_grid(make);
  expect_delta_tracking_exact(affine_vdb(file("g.vdb")), affine_ray(vdb->transform()), rng);
}

TEST_F(Media, RatioTrackingIsUnbiased) {
  std::mt19937_64 rng(test_seed());
  SCOPED_TRACE("STF_TEST_SEED=" + std::to_string(test_seed()));
  const DensityGrid cloud = cloud_grid();
  for (const Ray& ray : cloud_rays()) {
    SCOPED_TRACE("cloud ray from " + std::to_string(ray.o.x) + ", " + std::to_string(ray.o.y) + ", " + std::to_string(ray.o.z));
    expect_ratio_tracking_exact(cloud, ray, rng);
  }
  std::mt19937_64 make(7);
  const auto vdb = affine_grid(make);
  expect_ratio_tracking_exact(affine_vdb(file("g.vdb")), affine_ray(vdb->transform()), rng);
}

// Through constant bricks ratio tracking samples nothing and is exact: lattice x from 8 to 30
// (bricks 1 to 3 of a 32^3 grid; bricks 0 and 4 hold the padding) at y = z = 12.
TEST_F(Media, RatioTrackingIsExactThroughConstantBricks) {
  const DensityGrid grid = DensityGrid::from_values(std::vector<float>(32 * 32 * 32, 2.5f), 32, 32, 32, {{0, 0, 0}, {1, 1, 1}});
  std::mt19937_64 rng(test_seed());
  std::uniform_real_distribution<double> uniform(0, 1);
  auto u = [&] { return uniform(rng); };
  const Vec3 o{8.5 / 32, 12.5 / 32, 12.5 / 32};
  for (const Vec3& w : {Vec3{1, 0, 0}, normalize({1, 0.5, -0.25})}) {
    const double t_max = 22.0 / 32;
    const stf::media::Transmittance t = stf::media::ratio_track(grid, 3.0, o, w, t_max, u);
    EXPECT_NEAR(t.transmittance, std::exp(-3.0 * 2.5 * t_max), 1e-12);
    EXPECT_EQ(t.tentative, 0);
  }
  EXPECT_DOUBLE_EQ(stf::media::ratio_track(grid, 3.0, {2, 2, 2}, {1, 0, 0}, 10.0, u).transmittance, 1.0);  // misses
  EXPECT_FALSE(stf::media::delta_track(grid, 3.0, {2, 2, 2}, {1, 0, 0}, 10.0, u).collided);
}

// ---- refused grids -------------------------------------------------------------------------

std::function<void()> reading(const std::string& path, const std::optional<Box>& bounds) {
  return [=] { DensityGrid::read(path, bounds); };
}

TEST_F(Media, MissingFilesAndWrongBoundsAreOneLine) {
  expect_refusal(reading(file("none.npy"), kBounds), file("none.npy"), {"cannot open", "no such file"});
  expect_refusal(reading(file("none.vdb"), std::nullopt), file("none.vdb"), {"cannot open", "no such file"});
  fs::create_directories(file("dir.vdb"));
  expect_refusal(reading(file("dir.vdb"), std::nullopt), file("dir.vdb"), {"directory"});
  write_npy(file("a.npy"), small_values(), kNx, kNy, kNz);
  expect_refusal(reading(file("a.npy"), std::nullopt), file("a.npy"), {"needs bounds"});
  expect_refusal(reading(file("a.npy"), Box{{0, 0, 0}, {1, -1, 1}}), file("a.npy"), {"bounds on y", "below"});
  expect_refusal(reading(file("a.npy"), Box{{0, 0, NAN}, {1, 1, 1}}), file("a.npy"), {"bounds on z", "not finite"});
  expect_refusal(reading(file("a.npy"), Box{{0, 0, 0}, {INFINITY, 1, 1}}), file("a.npy"), {"bounds on x", "not finite"});
  expect_refusal(reading(file("g.vdb"), kBounds), file("g.vdb"), {"bounds are not taken"});
  expect_refusal(reading(file("a.raw"), kBounds), file("a.raw"), {".vdb or .npy"});
  EXPECT_THROW(DensityGrid::from_values({1, 2, 3}, 2, 2, 1, kBounds), std::invalid_argument);
}

TEST_F(Media, BadNpyFilesAreOneLine) {
  const std::string data = raw<float>(small_values());
  const std::vector<std::pair<std::string, std::vector<std::string>>> cases = {
      {npy_bytes(npy_dict("<i4", "(3, 4, 5)"), 1, data), {"dtype '<i4'", "float32"}},
      {npy_bytes(npy_dict(">f4", "(3, 4, 5)"), 1, data), {"dtype '>f4'", "little-endian"}},
      {npy_bytes(npy_dict("<f4", "(12, 5)"), 1, data), {"shape (12, 5)", "not 3-D"}},
      {npy_bytes(npy_dict("<f4", "(3, 0, 5)"), 1, ""), {"shape (3, 0, 5)", "zero dimension"}},
      {npy_bytes(npy_dict("<f4", "(3, 4, 5)", true), 1, data), {"fortran_order is True"}},
      {npy_bytes(npy_dict("<f4", "(3, 4, 5)"), 1, data.substr(0, 100)), {"truncated", "100 bytes", "need 240"}},
      {npy_bytes(npy_dict("<f4", "(3, 4, 5)"), 4, data), {"version 4.0"}},
      {npy_bytes("{'descr': '<f4', 'shape': (3, 4, 5), }", 1, data), {"unreadable .npy header", "fortran_order"}},
      {"not numpy at all", {"not a .npy file"}},
  };
  for (std::size_t c = 0; c < cases.size(); ++c) {
    const std::string path = file("bad" + std::to_string(c) + ".npy");
    write_file(path, cases[c].first);
    expect_refusal(reading(path, kBounds), path, cases[c].second);
  }
}

TEST_F(Media, BadValuesAreOneLineNamingTheFirst) {
  std::vector<double> values = small_values();
  values[std::size_t((1 * kNy + 2) * kNz + 3)] = -0.5;
  values[std::size_t((2 * kNy + 0) * kNz + 1)] = -2;
  write_npy(file("neg.npy"), values, kNx, kNy, kNz);
  expect_refusal(reading(file("neg.npy"), kBounds), file("neg.npy"), {"negative density -0.5 at [1, 2, 3]"});
  values = small_values();
  values[7] = NAN;
  write_npy(file("nan.npy"), values, kNx, kNy, kNz, true);
  expect_refusal(reading(file("nan.npy"), kBounds), file("nan.npy"), {"non-finite density", "[0, 1, 2]"});
  values[7] = 1e300;
  write_npy(file("big.npy"), values, kNx, kNy, kNz, true);
  expect_refusal(reading(file("big.npy"), kBounds), file("big.npy"), {"[0, 1, 2]", "float's range"});
  write_npy(file("zero.npy"), std::vector<double>(kNx * kNy * kNz, 0.0), kNx, kNy, kNz);
  expect_refusal(reading(file("zero.npy"), kBounds), file("zero.npy"), {"no non-zero density"});

  auto grid = vdb_grid("density", openvdb::math::Transform::createLinearTransform(1.0));
  grid->tree().setValue(Coord(-3, 4, 5), 1.0f);
  grid->tree().setValue(Coord(-2, 7, 9), -1.0f);
  write_vdb(file("neg.vdb"), {grid});
  expect_refusal(reading(file("neg.vdb"), std::nullopt), file("neg.vdb"), {"negative density -1 at index (-2, 7, 9)"});
  write_vdb(file("empty.vdb"), {vdb_grid("density", openvdb::math::Transform::createLinearTransform(1.0), 3.0f)});
  expect_refusal(reading(file("empty.vdb"), std::nullopt), file("empty.vdb"), {"no active voxel"});
  auto zeros = vdb_grid("density", openvdb::math::Transform::createLinearTransform(1.0));
  zeros->tree().setValue(Coord(1, 1, 1), 0.0f);
  write_vdb(file("zeros.vdb"), {zeros});
  expect_refusal(reading(file("zeros.vdb"), std::nullopt), file("zeros.vdb"), {"no non-zero density"});
}

TEST_F(Media, BadVdbFilesAreOneLine) {
  const auto unit = [] { return openvdb::math::Transform::createLinearTransform(1.0); };
  auto vectors = openvdb::Vec3SGrid::create();
  vectors->setName("density");
  write_vdb(file("vec.vdb"), {vectors});
  expect_refusal(reading(file("vec.vdb"), std::nullopt), file("vec.vdb"), {"no float grid", "'density' vec3s"});
  auto smoke = vdb_grid("smoke", unit()), heat = vdb_grid("heat", unit());
  smoke->tree().setValue(Coord(0, 0, 0), 1.0f), heat->tree().setValue(Coord(0, 0, 0), 1.0f);
  write_vdb(file("two.vdb"), {smoke, heat});
  expect_refusal(reading(file("two.vdb"), std::nullopt), file("two.vdb"), {"2 float grids", "none is named 'density'", "'smoke'"});
  auto density = vdb_grid("density", unit());  // named 'density': chosen among several
  density->tree().setValue(Coord(0, 0, 0), 4.0f);
  write_vdb(file("three.vdb"), {smoke, density, heat});
  EXPECT_DOUBLE_EQ(DensityGrid::read(file("three.vdb"), std::nullopt).density({0, 0, 0}), 4.0);

  auto frustum = vdb_grid("density", openvdb::math::Transform::createFrustumTransform(
                                         openvdb::BBoxd(Vec3d(0, 0, 0), Vec3d(10, 10, 10)), 0.5, 5.0, 1.0));
  frustum->tree().setValue(Coord(1, 1, 1), 1.0f);
  write_vdb(file("frustum.vdb"), {frustum});
  expect_refusal(reading(file("frustum.vdb"), std::nullopt), file("frustum.vdb"), {"transform", "linear"});
  write_file(file("junk.vdb"), "not a vdb file at all");
  expect_refusal(reading(file("junk.vdb"), std::nullopt), file("junk.vdb"), {"unreadable .vdb file"});
}

// Too large for memory: refused from the header (.npy) or the metadata (.vdb) before any value
// is read, so files whose values were cut off say so too.
TEST_F(Media, GridsTooLargeForMemoryAreRefusedBeforeTheirValues) {
  write_file(file("huge.npy"), npy_bytes(npy_dict("<f4", "(100000, 100000, 100000)"), 1, ""));
  expect_refusal(reading(file("huge.npy"), kBounds), file("huge.npy"), {"100000 x 100000 x 100000", "GiB", "available memory"});
  auto grid = vdb_grid("density", openvdb::math::Transform::createLinearTransform(1.0));
  grid->tree().setValue(Coord(0, 0, 0), 1.0f);
  grid->tree().setValue(Coord(400000, 400000, 400000), 1.0f);
  write_vdb(file("huge.vdb"), {grid});
  fs::resize_file(file("huge.vdb"), fs::file_size(file("huge.vdb")) - 64);  // the tree's end cut off
  expect_refusal(reading(file("huge.vdb"), std::nullopt), file("huge.vdb"), {"400001 x 400001 x 400001", "GiB"});
}

}  // namespace
