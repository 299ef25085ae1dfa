// Spherical harmonics: the basis, projection of band-limited densities, the window.
#include "sh_fit.h"

#include <gtest/gtest.h>

#include <cmath>

#include "stf/core/rng.h"
#include "stf/sh.h"

namespace stf::fit {
namespace {

// A positive band-limited density with every (l, m) present, and its exact cell masses.
std::vector<double> band_limited(int L) {
  std::vector<double> c(sh_count(L));
  std::uint64_t s = 5;
  for (double& v : c) v = 0.02 * (double(splitmix64(s) >> 11) * 0x1p-53 - 0.5);
  c[0] = 1 / std::sqrt(4 * kPi);
  return c;
}

TEST(ShBasis, OrthonormalOnTheSphere) {
  const int L = 6, count = sh_count(L);
  auto grid = make_grid("healpix:32");
  CellQuadrature q = grid->quadrature(1);
  std::vector<double> basis = sh_basis_at(q, L);
  for (int i = 0; i < count; ++i)
    for (int j = 0; j <= i; ++j) {
      double s = 0;
      for (std::size_t k = 0; k < q.point.size(); ++k) s += q.weight[k] * basis[k * count + i] * basis[k * count + j];
      EXPECT_NEAR(s, i == j ? 1.0 : 0.0, 2e-3) << i << "," << j;
    }
}

// HEALPix through map2alm_iter on pixel-centre values; the cube by least squares on cell
// averages. Counts are the exact cell masses; the coefficients come back to round-off (the
// cube) or to map2alm_iter's iterative accuracy (HEALPix, band limit well below 3 NSIDE).
TEST(ShProjector, ReproducesBandLimitedDensities) {
  const int L = 8;
  std::vector<double> truth = band_limited(L);
  for (const char* spec : {"healpix:16", "csc:12"}) {
    auto grid = make_grid(spec);
    std::vector<double> counts(grid->cell_count());
    if (std::string(spec).starts_with("healpix")) {
      std::vector<double> omega = grid->solid_angles();
      for (std::int64_t c = 0; c < grid->cell_count(); ++c) counts[c] = sh_eval(L, truth.data(), grid->centre(c)) * omega[c];
    } else {
      CellQuadrature q = grid->quadrature(2);  // what the projector averages the basis with
      for (std::size_t k = 0; k < q.point.size(); ++k) counts[k / q.per_cell] += q.weight[k] * sh_eval(L, truth.data(), q.point[k]);
    }
    ShProjector projector(*grid, L);
    std::vector<double> got = projector.project(counts);
    double scale = 0;
    for (double v : counts) scale += v;  // project() divides by the counts' total
    for (int i = 0; i < sh_count(L); ++i) EXPECT_NEAR(got[i] * scale, truth[i], 1e-9) << spec << " coefficient " << i;
  }
}

// A step (a uniform cap z > 0.5) rings when truncated at L = 16; Lanczos sigma factors cut
// the negative overshoot while the mass (a_00) and the cap's centroid (a_10) barely move.
TEST(ShSmoothing, WindowRemovesRingingWithoutMovingMass) {
  const int L = 16;
  auto grid = make_grid("healpix:32");
  std::vector<double> counts(grid->cell_count(), 0);
  for (std::int64_t c = 0; c < grid->cell_count(); ++c) counts[c] = grid->centre(c).z > 0.5 ? 1 : 0;
  ShProjector projector(*grid, L);
  std::vector<double> raw = projector.project(counts), windowed = raw;
  smooth_sh(windowed, L, {true, 0});
  auto min_value = [&](const std::vector<double>& c) {
    double m = 1e300;
    for (int i = 0; i < 20000; ++i) {
      double z = -1 + 2 * (i + 0.5) / 20000;
      m = std::min(m, sh_eval(L, c.data(), {std::sqrt(1 - z * z), 0, z}));
    }
    return m;
  };
  double peak = sh_eval(L, raw.data(), {0, 0, 1});
  EXPECT_LT(min_value(raw), -0.02 * peak);                     // the truncated step rings
  EXPECT_GT(min_value(windowed), 0.25 * min_value(raw));       // the window removes most of it
  EXPECT_DOUBLE_EQ(windowed[0], raw[0]);                       // total mass untouched
  EXPECT_NEAR(windowed[2], raw[2], 0.01 * std::abs(raw[2]));   // centroid (l = 1, m = 0) kept
}

TEST(ShSmoothing, ClampedDensityIsNonNegativeAndNormalised) {
  const int L = 12;
  auto grid = make_grid("csc:8");
  CellQuadrature q = grid->quadrature(1);
  std::vector<double> c(sh_count(L), 0.0);
  c[0] = 1 / std::sqrt(4 * kPi);
  c[6] = 0.5;  // large enough to go negative somewhere
  std::vector<double> p = clamped_sh_cell_probabilities(c, sh_basis_at(q, L), q);
  double s = 0;
  for (double v : p) {
    EXPECT_GE(v, 0);
    s += v;
  }
  EXPECT_NEAR(s, 1, 1e-12);
}

}  // namespace
}  // namespace stf::fit
