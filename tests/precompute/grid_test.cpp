#include "stf/core/grid.h"

#include <gtest/gtest.h>
#include <healpix_base.h>
#include <wcslib/prj.h>

#include <cmath>
#include <numeric>
#include <stdexcept>

#include "chi2.h"
#include "stf/core/rng.h"
#include "seed.h"

namespace stf {
namespace {

const char* kSpecs[] = {"csc:1", "csc:2", "csc:9", "csc:45", "healpix:1", "healpix:4", "healpix:16"};

Vec3 uniform_direction(std::uint64_t& state) {
  double z = 2 * (double(splitmix64(state) >> 11) * 0x1p-53) - 1;
  double phi = 2 * kPi * (double(splitmix64(state) >> 11) * 0x1p-53);
  double r = std::sqrt(std::max(0.0, 1 - z * z));
  return {r * std::cos(phi), r * std::sin(phi), z};
}

TEST(Grid, ParsesSpecsAndRejectsBadOnes) {
  EXPECT_EQ(make_grid("csc:45")->cell_count(), 6 * 45 * 45);
  EXPECT_EQ(make_grid("healpix:16")->cell_count(), 12 * 16 * 16);
  EXPECT_EQ(make_grid("healpix:16")->spec(), "healpix:16");
  for (const char* bad : {"", "csc", "csc:", "csc:0", "csc:-3", "csc:4x", "healpix:3", "healpix:0",
                          "cube:4", "csc:100000", "healpix:16384"})
    EXPECT_THROW(make_grid(bad), std::invalid_argument) << bad;
}

TEST(Grid, EveryDirectionLandsInOneValidCell) {
  std::uint64_t state = test::test_seed(21);
  SCOPED_TRACE(test::seed_trace(state));
  for (const char* spec : kSpecs) {
    auto grid = make_grid(spec);
    for (int i = 0; i < 20000; ++i) {
      Vec3 d = uniform_direction(state);
      std::int64_t c = grid->cell(d);
      ASSERT_GE(c, 0) << spec;
      ASSERT_LT(c, grid->cell_count()) << spec;
    }
    // Axes, poles and face edges and corners of the cube, where layouts break first.
    for (Vec3 d : {Vec3{0, 0, 1}, Vec3{0, 0, -1}, Vec3{1, 0, 0}, Vec3{-1, 0, 0}, Vec3{0, 1, 0},
                   Vec3{0, -1, 0}, normalize({1, 1, 0}), normalize({-1, -1, 0}), normalize({1, 0, 1}),
                   normalize({1, 1, 1}), normalize({-1, 1, -1}), normalize({-1, -1e-17, 0})}) {
      std::int64_t c = grid->cell(d);
      EXPECT_TRUE(c >= 0 && c < grid->cell_count()) << spec;
    }
  }
}

TEST(Grid, CellCentreMapsBackToItsCell) {
  for (const char* spec : kSpecs) {
    auto grid = make_grid(spec);
    for (std::int64_t c = 0; c < grid->cell_count(); ++c) {
      Vec3 v = grid->centre(c);
      ASSERT_NEAR(length(v), 1.0, 1e-12) << spec;
      ASSERT_EQ(grid->cell(v), c) << spec << " centre of cell " << c;
    }
  }
}

TEST(Grid, SolidAnglesArePositiveAndSumToFourPi) {
  for (const char* spec : kSpecs) {
    auto grid = make_grid(spec);
    std::vector<double> omega = grid->solid_angles();
    ASSERT_EQ(std::int64_t(omega.size()), grid->cell_count());
    for (double w : omega) ASSERT_GT(w, 0) << spec;
    // HEALPix is exact. The cube's faces are measured separately through WCSLIB's inverse,
    // which works in single precision, so the shared edges of two faces may part by ~1e-7 rad:
    // over the cube's 12 edges (length ~19) at most ~2e-6 sr.
    double tolerance = std::string(spec).starts_with("csc") ? 2e-6 : 1e-12;
    EXPECT_NEAR(std::accumulate(omega.begin(), omega.end(), 0.0), 4 * kPi, tolerance) << spec;
  }
}

TEST(Grid, CscIsNotEqualAreaButCloseToIt) {
  std::vector<double> omega = CscGrid(45).solid_angles();
  auto [lo, hi] = std::minmax_element(omega.begin(), omega.end());
  double mean = 4 * kPi / double(omega.size());
  EXPECT_GT(*hi / *lo, 1.01);  // assuming equal cells would be wrong by more than 1%
  EXPECT_LT(*hi / mean, 1.5);
  EXPECT_GT(*lo / mean, 0.5);
}

// Uniform directions fall into cells in proportion to their solid angles: this checks the
// solid angles against the forward map that bins directions (not the inverse that measured
// them), and that the cells cover the sphere without gaps or overlaps.
TEST(Grid, SolidAnglesMatchUniformDirectionCountsChiSquare) {
  const std::uint64_t seed = test::test_seed(22);
  SCOPED_TRACE(test::seed_trace(seed));
  for (const char* spec : {"csc:9", "healpix:4"}) {
    auto grid = make_grid(spec);
    std::vector<double> omega = grid->solid_angles();
    const int n = 4'000'000;
    std::vector<double> observed(omega.size(), 0), expected(omega.size());
    for (std::size_t c = 0; c < omega.size(); ++c) expected[c] = n * omega[c] / (4 * kPi);
    std::uint64_t state = seed;
    for (int i = 0; i < n; ++i) observed[grid->cell(uniform_direction(state))] += 1;
    test::Chi2Result r = test::chi2_test(observed, expected);
    EXPECT_GT(r.p_value, test::kChi2Alpha) << spec << ": " << r.describe();
  }
}

// The cube layout follows WCSLIB: each face's centre direction projects (cscs2x) to that
// face's centre in WCSLIB's plane, and the cell index runs face-major, then row (plane y),
// then column (plane x), from the bottom left.
TEST(Grid, CscFaceLayoutMatchesWcslib) {
  const int n = 5;
  CscGrid grid(n);
  prjprm prj;
  prjini(&prj);
  ASSERT_EQ(cscset(&prj), 0);
  const Vec3 axes[6] = {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}, {0, 0, -1}};
  for (int face = 0; face < 6; ++face) {
    const Vec3& a = axes[face];
    double phi = std::atan2(a.y, a.x) * 180 / kPi, theta = std::asin(a.z) * 180 / kPi, x, y;
    int stat;
    cscs2x(&prj, 1, 1, 1, 1, &phi, &theta, &x, &y, &stat);
    double x0, y0;
    CscGrid::face_offset(face, x0, y0);
    EXPECT_NEAR(std::fmod(x - x0 + 720, 360), 0, 1e-6) << "face " << face;
    EXPECT_NEAR(y, y0, 1e-6) << "face " << face;
    // The face's centre cell (odd n) holds the axis.
    EXPECT_EQ(grid.cell(a), (face * n + n / 2) * n + n / 2) << "face " << face;
    // One cell right in plane x is the next column; one cell up in plane y the next row.
    for (auto [dx, dy, step] : {std::tuple{1, 0, 1}, std::tuple{0, 1, n}}) {
      Vec3 d = grid.face_point(face, 2.0 * dx / n, 2.0 * dy / n);
      EXPECT_EQ(grid.cell(d), grid.cell(a) + step) << "face " << face;
    }
  }
}

// Polar cells are as fine in solid angle as equatorial ones (equal area is checked against
// uniform directions above): the pole itself is a corner of the four first-ring cells, not
// the centre of one wide cell.
TEST(Grid, HealpixPoleIsACornerOfFourCells) {
  HealpixGrid grid(8);
  std::int64_t north = grid.cell({0, 0, 1});
  EXPECT_LT(north, 4);
  for (double phi : {0.3, 1.9, 3.5, 5.1})  // just off the pole, one per quadrant
    EXPECT_EQ(grid.cell(normalize({1e-3 * std::cos(phi), 1e-3 * std::sin(phi), 1})), std::int64_t(phi / (kPi / 2)));
}

// Sub-cells partition their cell: weights sum to the cell's solid angle, and every sub-cell
// centre lies in its own cell.
TEST(Grid, QuadratureSubCellsPartitionEachCell) {
  for (const char* spec : {"csc:3", "csc:10", "healpix:2", "healpix:8"}) {
    auto grid = make_grid(spec);
    std::vector<double> omega = grid->solid_angles();
    for (int level : {0, 1, 3}) {
      CellQuadrature q = grid->quadrature(level);
      ASSERT_EQ(q.per_cell, 1 << (2 * level));
      // HEALPix children partition exactly; the cube's sub-squares are rescaled to the cell's
      // solid angle, so for it the sum checks the rescaling.
      for (std::int64_t c = 0; c < grid->cell_count(); ++c) {
        double sum = 0;
        for (int j = 0; j < q.per_cell; ++j) {
          std::size_t k = std::size_t(c) * q.per_cell + j;
          sum += q.weight[k];
          ASSERT_EQ(grid->cell(q.point[k]), c) << spec << " level " << level;
        }
        EXPECT_NEAR(sum, omega[c], 1e-12 * omega[c]) << spec << " level " << level;
      }
    }
  }
}

// stf's own RING lookup against healpix_cxx's vec2pix: identical but within ~1e-8 rad of a
// cell edge, where the two atan2s may round differently.
TEST(Grid, HealpixLookupAgreesWithHealpixCxx) {
  std::uint64_t state = test::test_seed(23);
  SCOPED_TRACE(test::seed_trace(state));
  for (int nside : {1, 2, 16, 256, 8192}) {
    HealpixGrid grid(nside);
    T_Healpix_Base<int64> reference(nside, RING, SET_NSIDE);
    int disagree = 0;
    const int n = 200'000;
    for (int i = 0; i < n; ++i) {
      Vec3 d = uniform_direction(state);
      if (grid.cell(d) != reference.vec2pix(vec3(d.x, d.y, d.z))) ++disagree;
    }
    // Cell edges total ~25 nside rad; a band of +-1e-8 rad around them is ~4e-8 nside of the
    // sphere. The bound allows 2.5 times that.
    EXPECT_LE(disagree, 1 + n * 1e-7 * nside) << "nside " << nside;
    for (Vec3 d : {Vec3{0, 0, 1}, Vec3{0, 0, -1}, Vec3{1, 0, 0}, Vec3{-1, 0, 0}, Vec3{0, -1, 0}}) {
      std::int64_t c = grid.cell(d);
      EXPECT_TRUE(c >= 0 && c < grid.cell_count()) << "nside " << nside;
    }
  }
}

TEST(Grid, BatchLookupEqualsSingleLookup) {
  std::uint64_t state = test::test_seed(24);
  for (const char* spec : {"csc:7", "healpix:8"}) {
    auto grid = make_grid(spec);
    std::vector<double> x(257), y(257), z(257);
    std::vector<std::int64_t> out(257);
    for (std::size_t i = 0; i < x.size(); ++i) {
      Vec3 d = uniform_direction(state);
      x[i] = d.x, y[i] = d.y, z[i] = d.z;
    }
    grid->cells(x.data(), y.data(), z.data(), out.data(), int(x.size()));
    for (std::size_t i = 0; i < x.size(); ++i) EXPECT_EQ(out[i], grid->cell({x[i], y[i], z[i]})) << spec;
  }
}

}  // namespace
}  // namespace stf
