// vMF fitting: mixtures drawn as direction samples, binned by the grid, fitted back.
#include "stf/fit/vmf_fit.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "stf/fit/cell_integral.h"
#include "stf/fit/exp_in_place.h"
#include "stf/hemisphere.h"
#include "reference_cells.h"
#include "stf/core/rng.h"
#include "seed.h"

namespace stf::fit {
namespace {

double uniform(std::uint64_t& s) { return double(splitmix64(s) >> 11) * 0x1p-53; }

// Histogram of n directions drawn from the mixture, binned on `grid`.
std::vector<double> draw_histogram(const std::vector<VmfLobe>& lobes, const DirectionGrid& grid,
                                   std::int64_t n, std::uint64_t seed) {
  std::vector<double> counts(grid.cell_count(), 0);
  std::uint64_t s = seed;
  for (std::int64_t i = 0; i < n; ++i) {
    double pick = uniform(s);
    std::size_t k = 0;
    while (k + 1 < lobes.size() && pick >= lobes[k].weight) pick -= lobes[k++].weight;
    counts[grid.cell(sample_vmf(lobes[k], uniform(s), uniform(s)))] += 1;
  }
  return counts;
}

double tv(const std::vector<double>& p, const std::vector<double>& q) {
  double s = 0;
  for (std::size_t i = 0; i < p.size(); ++i) s += std::abs(p[i] - q[i]);
  return 0.5 * s;
}

std::vector<double> normalised(std::vector<double> v) {
  double s = 0;
  for (double x : v) s += x;
  for (double& x : v) x /= s;
  return v;
}

struct Recovery {
  double tv_fit, tv_histogram;
  double deviance_fit, deviance_truth;  // on the same quadrature
  VmfFitResult fit;
};

Recovery recover(const std::vector<VmfLobe>& truth, const char* spec, std::int64_t n, std::uint64_t seed) {
  auto grid = make_grid(spec);
  QuadratureLevels levels(*grid);
  std::vector<double> counts = draw_histogram(truth, *grid, n, seed);
  VmfFitResult fit = fit_vmf(counts, levels, int(truth.size()));
  // "Exact" cell probabilities: a quadrature a level finer than the fit could use.
  CellQuadrature fine = grid->quadrature(QuadratureLevels::kMaxLevel + 1);
  std::vector<double> exact = test::reference_cells(truth, fine), fitted = test::reference_cells(fit.lobes, fine);
  return {tv(fitted, exact), tv(normalised(counts), exact), poisson_deviance(counts, fitted),
          poisson_deviance(counts, exact), fit};
}

// The optimiser found the maximum likelihood: the fit explains the data at least as well as
// the truth it was drawn from (up to the quadrature's own error, well below one unit).
void expect_maximum_likelihood(const Recovery& r) {
  EXPECT_LE(r.deviance_fit, r.deviance_truth + 0.5) << "fit " << r.deviance_fit << ", truth " << r.deviance_truth;
}

double angle(const Vec3& a, const Vec3& b) { return std::acos(std::clamp(dot(a, b), -1.0, 1.0)); }

// One lobe: the mean is known to ~1/sqrt(kappa n) per axis and kappa to ~kappa sqrt(2/n)
// (large kappa; Fisher information of the vMF), both within 6 sigma.
// The lobe integrals take their exponentials several at a time (exp_in_place): within 4 units
// in the last place of std::exp over every exponent they meet (40 e-folds and the widening's
// margin below the peak), at any batch length and alignment.
TEST(VmfFit, BatchedExponentialsMatchStdExp) {
  std::vector<double> x;
  for (int k = 0; k <= 600000; ++k) x.push_back(-60.0 * k / 600000);
  for (double v : {0.0, -1e-300, -1e-17, -0.5, -1.0, -745.0}) x.push_back(v);
  double worst = 0;
  for (int n : {int(x.size()) - 1, 1, 3, 63}) {
    std::vector<double> y(x.begin() + 1, x.begin() + 1 + n);  // odd start: unaligned
    exp_in_place(y.data(), n);
    for (int i = 0; i < n; ++i) {
      const double exact = std::exp(x[std::size_t(i) + 1]);
      const double ulp = std::nextafter(exact, 1e300) - exact;
      worst = std::max(worst, std::abs(y[std::size_t(i)] - exact) / ulp);
    }
  }
  EXPECT_LE(worst, 4.0);
}

// A lobe's integrals visit only the cells of QuadratureLevels::cell_range: every cell whose
// centre lies within the reach of the mean must be inside it, on a grid numbered ring by ring
// (HEALPix, where narrow lobes get short runs) and on one that is not (CSC).
TEST(VmfFit, CellRangesHoldEveryCellWithinReach) {
  for (const char* spec : {"healpix:8", "csc:12"}) {
    auto grid = make_grid(spec);
    QuadratureLevels levels(*grid);
    const std::vector<Vec3>& centre = levels.centres();
    std::uint64_t state = 7;
    std::size_t visited = 0, tries = 0;
    for (int k = 0; k < 2000; ++k) {
      const double z = 2 * uniform(state) - 1, phi = 2 * kPi * uniform(state), r = std::sqrt(1 - z * z);
      const Vec3 mean = k < 4 ? Vec3{0, 0, k % 2 ? 1.0 : -1.0} : Vec3{r * std::cos(phi), r * std::sin(phi), z};
      const double reach = k % 5 == 0 ? kPi : 0.5 * uniform(state);
      const auto [first, last] = levels.cell_range(mean, reach);
      ASSERT_LE(first, last);
      ASSERT_LE(last, centre.size());
      for (std::size_t c = 0; c < centre.size(); ++c) {
        if (dot(mean, centre[c]) >= std::cos(reach)) {
          ASSERT_TRUE(c >= first && c < last) << spec << " cell " << c;
        }
      }
      visited += last - first, tries += centre.size();
    }
    if (std::string(spec) == "healpix:8") {
      EXPECT_LT(double(visited), 0.5 * double(tries));  // runs, not the sphere
    }
  }
}

TEST(VmfFit, RecoversOneLobe) {
  const std::uint64_t seed = test::test_seed(41);
  SCOPED_TRACE(test::seed_trace(seed));
  const std::int64_t n = 400'000;
  for (double kappa : {3.0, 30.0, 300.0}) {
    VmfLobe truth{1, kappa, normalize({0.3, -0.5, 0.8})};
    Recovery r = recover({truth}, "healpix:16", n, seed);
    const VmfLobe& got = r.fit.lobes[0];
    EXPECT_LT(angle(got.mean, truth.mean), 6 / std::sqrt(kappa * n)) << "kappa " << kappa;
    EXPECT_NEAR(got.kappa, kappa, 6 * kappa * std::sqrt(2.0 / n) + 0.01 * kappa) << "kappa " << kappa;
    EXPECT_LT(r.tv_fit, 0.25 * r.tv_histogram) << "kappa " << kappa;
    expect_maximum_likelihood(r);
  }
}

// kappa -> 0: the resultant length R ~ kappa / 3 has standard error 1 / sqrt(3 n).
TEST(VmfFit, NearlyUniformLobe) {
  const std::uint64_t seed = test::test_seed(42);
  const std::int64_t n = 400'000;
  Recovery r = recover({VmfLobe{1, 0.1, {0, 0, 1}}}, "healpix:8", n, seed);
  EXPECT_NEAR(r.fit.lobes[0].kappa, 0.1, 6 * 3 / std::sqrt(3.0 * n));
  EXPECT_TRUE(std::isfinite(r.fit.lobes[0].mean.z));
  expect_maximum_likelihood(r);
}

// kappa = 1e5 is far narrower than a cell (0.06 rad): only "all in these cells" is knowable;
// the fit must be finite, put its mass where the samples are, and sit inside the right cell.
TEST(VmfFit, NearDeltaLobe) {
  const std::uint64_t seed = test::test_seed(43);
  VmfLobe truth{1, 1e5, normalize({0.2, 0.1, 0.97})};
  Recovery r = recover({truth}, "healpix:16", 100'000, seed);
  const VmfLobe& got = r.fit.lobes[0];
  EXPECT_TRUE(std::isfinite(got.kappa));
  EXPECT_GT(got.kappa, 1e3);
  EXPECT_LT(angle(got.mean, truth.mean), 0.06);
  EXPECT_LT(r.tv_fit, 0.02);
}

TEST(VmfFit, RecoversSeparatedMixtures) {
  const std::uint64_t seed = test::test_seed(44);
  SCOPED_TRACE(test::seed_trace(seed));
  const std::vector<std::vector<VmfLobe>> cases = {
      // near-antipodal
      {{0.7, 20, normalize({0, 0.05, 1})}, {0.3, 50, normalize({0.05, 0, -1})}},
      {{0.5, 10, {1, 0, 0}}, {0.3, 40, {0, 1, 0}}, {0.2, 100, {0, 0, -1}}},
      {{0.4, 5, {0, 0, 1}}, {0.3, 30, {1, 0, 0}}, {0.2, 60, {-1, 0, 0}}, {0.1, 200, {0, -1, 0}}},
  };
  const std::int64_t n = 800'000;
  for (const auto& truth : cases) {
    Recovery r = recover(truth, "healpix:16", n, seed);
    // Match each true lobe to the nearest fitted mean.
    for (const VmfLobe& t : truth) {
      const VmfLobe* best = &r.fit.lobes[0];
      for (const VmfLobe& f : r.fit.lobes)
        if (dot(f.mean, t.mean) > dot(best->mean, t.mean)) best = &f;
      double nk = t.weight * n;
      EXPECT_LT(angle(best->mean, t.mean), 6 / std::sqrt(t.kappa * nk)) << truth.size() << " lobes";
      EXPECT_NEAR(best->kappa, t.kappa, 6 * t.kappa * std::sqrt(2.0 / nk) + 0.02 * t.kappa);
      EXPECT_NEAR(best->weight, t.weight, 6 * std::sqrt(t.weight * (1 - t.weight) / n));
    }
    EXPECT_LT(r.tv_fit, 0.25 * r.tv_histogram) << truth.size() << " lobes";
    expect_maximum_likelihood(r);
  }
}

// Lobes 10 degrees apart, the narrow one only a few cells wide: the likelihood is flat along
// trade-offs between the lobes, so the check is that the optimiser reached the maximum and the
// density is closer to the truth than the histogram.
TEST(VmfFit, NearCoincidentLobesFitTheDensity) {
  const std::uint64_t seed = test::test_seed(45);
  std::vector<VmfLobe> truth = {{0.6, 50, {0, 0, 1}}, {0.4, 500, normalize({0.17, 0, 0.98})}};
  Recovery r = recover(truth, "healpix:16", 400'000, seed);
  expect_maximum_likelihood(r);
  EXPECT_LT(r.tv_fit, r.tv_histogram);
  double weights = 0;
  for (const VmfLobe& l : r.fit.lobes) weights += l.weight;
  EXPECT_NEAR(weights, 1.0, 1e-12);
}

// A parameter that runs into its bound stays there and the others still converge: a lobe far
// narrower than a cell with kappa capped at 1e3, next to a broad one that must be recovered
// as if alone (its Fisher errors, as RecoversSeparatedMixtures), and a third lobe the data do
// not need, whose weight must fall without holding the fit back.
TEST(VmfFit, ParametersAtTheirBoundsDoNotHoldTheOthersBack) {
  const std::uint64_t seed = test::test_seed(47);
  SCOPED_TRACE(test::seed_trace(seed));
  const std::vector<VmfLobe> truth = {{0.5, 1e5, normalize({0.2, 0.1, 0.97})}, {0.5, 20, normalize({-1, 0.2, 0})}};
  auto grid = make_grid("healpix:16");
  QuadratureLevels levels(*grid);
  const std::int64_t n = 400'000;
  std::vector<double> counts = draw_histogram(truth, *grid, n, seed);
  VmfFitOptions options;
  options.max_kappa = 1e3;
  std::vector<VmfLobe> start = {{0.4, 300, normalize({0.25, 0.1, 0.96})}, {0.4, 5, normalize({-1, 0, 0.3})},
                                {0.2, 5, normalize({0, -1, 0})}};
  VmfFitResult fit = fit_vmf_from(counts, levels, start, options);
  const VmfLobe& narrow = fit.lobes[0];
  EXPECT_DOUBLE_EQ(narrow.kappa, 1e3);
  EXPECT_LT(angle(narrow.mean, truth[0].mean), 0.06);
  const VmfLobe& broad = *std::max_element(fit.lobes.begin() + 1, fit.lobes.end(),
                                           [](const VmfLobe& a, const VmfLobe& b) { return a.weight < b.weight; });
  const double nk = 0.5 * n;
  EXPECT_LT(angle(broad.mean, truth[1].mean), 6 / std::sqrt(20 * nk));
  EXPECT_NEAR(broad.kappa, 20, 6 * 20 * std::sqrt(2.0 / nk) + 0.02 * 20);
  // What the spare lobe keeps it takes from the broad one: together they hold its escapes.
  EXPECT_NEAR(narrow.weight, 0.5, 6 * std::sqrt(0.25 / n) + 1e-3);
  double weights = 0;
  for (const VmfLobe& l : fit.lobes) {
    weights += l.weight;
    EXPECT_LE(l.kappa, 1e3);
  }
  EXPECT_NEAR(weights, 1.0, 1e-12);
}

TEST(VmfFit, CellProbabilitiesOfANarrowLobeSumToOne) {
  auto grid = make_grid("csc:5");
  const QuadratureLevels levels(*grid);
  for (double kappa : {0.0, 1e-8, 1.0, 1e4, 1e7}) {
    std::vector<double> p = lobe_cell_probabilities({VmfLobe{1, kappa, normalize({1, 2, 3})}}, levels);
    double s = 0;
    for (double v : p) {
      ASSERT_TRUE(std::isfinite(v));
      s += v;
    }
    EXPECT_NEAR(s, 1.0, 1e-12) << kappa;
  }
}

// The cells far from a lobe keep their small mass (KL and deviances divide by it): the batched
// integrator agrees with the plain point rule on the points of the level it chose in every cell,
// the antipode of a kappa 300 lobe (e^-600 of its peak) included.
TEST(VmfFit, CellProbabilitiesKeepTheTailsOfNarrowLobes) {
  auto grid = make_grid("healpix:8");
  const QuadratureLevels levels(*grid);
  for (double kappa : {0.5, 30.0, 300.0}) {
    const std::vector<VmfLobe> lobe = {{1, kappa, normalize({1, 2, 3})}};
    const std::vector<double> p = lobe_cell_probabilities(lobe, levels);
    const std::vector<double> ref = test::reference_cells(lobe, levels.at(levels.level_for_kappa(kappa)));
    double worst = 0;
    for (std::size_t c = 0; c < p.size(); ++c) {
      ASSERT_GT(ref[c], 0) << kappa << " cell " << c;
      worst = std::max(worst, std::abs(p[c] / ref[c] - 1));
    }
    EXPECT_LT(worst, 1e-12) << kappa;
  }
}

TEST(VmfFit, StableDensityAndSamplingAtExtremeKappa) {
  EXPECT_NEAR(vmf_pdf(0.0, 0.3), 1 / (4 * kPi), 1e-15);
  EXPECT_NEAR(vmf_pdf(1e-10, -1.0), (1 - 1e-10) / (4 * kPi), 1e-17);  // (1 + k) e^{-2k} / 4 pi
  EXPECT_TRUE(std::isfinite(vmf_pdf(1e7, 1.0)));
  EXPECT_NEAR(vmf_pdf(1e7, 1.0), 1e7 / (2 * kPi), 1);
  EXPECT_EQ(vmf_pdf(1e7, -1.0), 0.0);
  for (double kappa : {0.0, 1e-12, 1.0, 1e7})
    for (double u : {0.0, 1e-300, 0.5, 1 - 1e-16}) EXPECT_TRUE(std::abs(sample_vmf_cos(kappa, u)) <= 1);
}

// Extra lobes never make a fit worse: a peaked histogram (most counts in a few cells) once
// gave k-means clusters of one cell, whose resultant of 1 started point lobes (kappa 1e7)
// that the binned likelihood could not widen: 12 lobes fitted several times worse than 8.
TEST(VmfFit, MoreLobesNeverFitAPeakedHistogramWorse) {
  const std::uint64_t seed = test::test_seed(47);
  SCOPED_TRACE(test::seed_trace(seed));
  auto grid = make_grid("healpix:8");
  QuadratureLevels levels(*grid);
  const std::vector<VmfLobe> truth = {{0.5, 3000, normalize({0, 0.02, 1})},
                                      {0.3, 600, normalize({0.05, 0, 1})},
                                      {0.2, 80, normalize({0.2, 0, 1})}};
  std::vector<double> counts = draw_histogram(truth, *grid, 1'000'000, seed);
  double previous = std::numeric_limits<double>::infinity();
  for (int K : {3, 4, 6, 8, 12, 16}) {
    VmfFitResult fit = fit_vmf(counts, levels, K);
    const double deviance = poisson_deviance(counts, lobe_cell_probabilities(fit.lobes, levels, 1e6));
    // Within a few units (the optimiser's tolerance), never a jump.
    EXPECT_LT(deviance, previous + 5) << K << " lobes";
    previous = std::min(previous, deviance);
  }
}

// Hemispherical lobes (each times its bin's mean outward cosine) against a cosine law on the
// outward hemisphere, the shape of diffuse exits: noise-free counts, so any error is the
// family's. Two such lobes hold it; plain lobes leak below the tangent plane and cannot form the
// grazing fall-off, even twelve of them.
TEST(VmfFit, HemisphericalLobesHoldACosineLawThatPlainLobesCannot) {
  auto grid = make_grid("healpix:8");
  QuadratureLevels levels(*grid);
  const double a0 = 0.6, a1 = 0.67;  // an alpha bin of 4 degrees
  auto law = [&](const Vec3& w) {
    double s = 0;  // the cosine to the exit normal, averaged over the bin, times a tilt
    for (int i = 0; i < 32; ++i) {
      const double a = a0 + (i + 0.5) / 32 * (a1 - a0);
      s += std::max(0.0, w.x * std::sin(a) + w.z * std::cos(a));
    }
    return s / 32 * (1 + 0.5 * w.z);
  };
  const std::vector<double> p = density_cell_probabilities(law, grid->quadrature(QuadratureLevels::kMaxLevel + 1));
  std::vector<double> counts(p.size());
  for (std::size_t c = 0; c < p.size(); ++c) counts[c] = 1e6 * p[c];
  const OutwardFactors outward = outward_factors(levels, a0, a1);
  VmfFitOptions hemi;
  hemi.outward = &outward;
  const VmfFitResult h = fit_vmf(counts, levels, 2, hemi), plain = fit_vmf(counts, levels, 12);
  const double tv_h = tv(lobe_cell_probabilities(h.lobes, levels, 1e6, &outward), p);
  const double tv_plain = tv(lobe_cell_probabilities(plain.lobes, levels, 1e6), p);
  EXPECT_LT(tv_h, 0.01);
  EXPECT_GT(tv_plain, 2 * tv_h);
}

// Lifted lobes (BinTurn::lifted, StfModel::lifted): a lobe's cell probabilities are its density
// 4 (w . n) vMF(2 (w . n) w - n) averaged over the exit normals n of the bin (uniform in area), as
// a fine midpoint integration of that density (16 times as many points, 64 exit angles) gives
// them (within 0.0004-0.0014 here): the points mapped about each normal with the reflection's
// Jacobian. Without the Jacobian the cells miss by 0.003-0.1.
TEST(VmfFit, LiftedLobeCellsAreTheDensityAveragedOverTheExitNormals) {
  auto grid = make_grid("healpix:16");
  QuadratureLevels levels(*grid);
  for (const BinTurn& bin : {BinTurn{0, 0.6, 0.67, 0.0, true}, BinTurn{1.5, 0.2, 0.4, 0.0, true}}) {
    for (const VmfLobe& l : {VmfLobe{1, 2, normalize({0.3, 0.2, 0.9})}, VmfLobe{1, 20, normalize({0.9, 0.1, -0.2})},
                             VmfLobe{1, 60, normalize({0.2, -0.1, 0.3})}}) {
      const double c0 = std::cos(bin.a0), c1 = std::cos(bin.a1), middle = 0.5 * (bin.a0 + bin.a1);
      auto density = [&](const Vec3& w) {
        double sum = 0;
        for (int i = 0; i < 64; ++i) {
          const double alpha = std::acos(c0 + (i + 0.5) / 64 * (c1 - c0));
          const Vec3 n{std::sin(alpha), 0, std::cos(alpha)}, mean = turn_about_y(l.mean, bin.rate * (alpha - middle));
          const double up = dot(w, n);
          if (up > 0) sum += 4 * up * vmf_pdf(l.kappa, dot(mean, 2 * up * w - n));
        }
        return sum / 64;
      };
      const std::vector<double> fine = density_cell_probabilities(density, grid->quadrature(QuadratureLevels::kMaxLevel + 1));
      EXPECT_LT(tv(lobe_cell_probabilities({l}, levels, 1e6, nullptr, &bin), fine), 2e-3) << "kappa " << l.kappa << " rate " << bin.rate;
    }
  }
}

// A bin whose density turns with the exit point (VmfFitOptions::turn): directions drawn from one
// narrow lobe turned by 1.5 (alpha - middle) at exit points uniform in the area of a bin 11.5
// degrees wide, so the turn across the bin (17 degrees) is five times the lobe's width. Fitted as
// the turned density averaged over the bin, the lobe comes back (mean to 6 / sqrt(kappa n) and
// kappa to 6 kappa sqrt(2 / n), plus 3% for the copies the fit integrates the turn with); fitted
// as a bin that stands still, one lobe can only widen over the turn.
TEST(VmfFit, TurningBinsRecoverTheLobeTheirExitPointsTurn) {
  const std::uint64_t seed = test::test_seed(44);
  SCOPED_TRACE(test::seed_trace(seed));
  auto grid = make_grid("healpix:16");
  QuadratureLevels levels(*grid);
  const BinTurn turn{1.5, 0.2, 0.4, 0.0};
  const VmfLobe truth{1, 300, normalize({0.5, 0.1, 0.8})};
  const std::int64_t n = 200'000;
  std::vector<double> counts(grid->cell_count(), 0.0);
  std::uint64_t s = seed;
  const double c0 = std::cos(turn.a0), c1 = std::cos(turn.a1);
  for (std::int64_t i = 0; i < n; ++i) {
    const double alpha = std::acos(c0 + uniform(s) * (c1 - c0));
    const Vec3 w = sample_vmf(truth, uniform(s), uniform(s));
    counts[grid->cell(turn_about_y(w, turn.rate * (alpha - 0.5 * (turn.a0 + turn.a1))))] += 1;
  }
  VmfFitOptions turning;
  turning.turn = &turn;
  const VmfLobe got = fit_vmf(counts, levels, 1, turning).lobes[0];
  EXPECT_LT(angle(got.mean, truth.mean), 6 / std::sqrt(truth.kappa * n));
  EXPECT_NEAR(got.kappa, truth.kappa, 6 * truth.kappa * std::sqrt(2.0 / n) + 0.03 * truth.kappa);
  const VmfLobe still = fit_vmf(counts, levels, 1).lobes[0];
  EXPECT_LT(still.kappa, 0.5 * truth.kappa);
}

// A hemispherical lobe integrated over the cells as `stf eval` does (outward_cell_means): a cell
// that the bin's tangent planes cut keeps its outward part, where the outward factor at the
// cells' points left the cut cells with their point below empty (up to 4e-7 of the lobe each
// here; only cells whose finest points all lie below, with under 4e-8, stay empty); and the
// cells are closer to a fine integration of the density (16 times as many points).
TEST(VmfFit, CellMeansOfTheOutwardFactorKeepTheCutCells) {
  auto grid = make_grid("healpix:8");
  QuadratureLevels levels(*grid);
  const double a0 = 0.6, a1 = 0.67;
  const VmfLobe lobe{1, 5, {std::sin(1.2), 0, std::cos(1.2)}};  // broad, leaning past the normal
  const OutwardBin factor(a0, a1);
  const std::vector<double> truth = density_cell_probabilities(
      [&](const Vec3& w) { return vmf_pdf(lobe.kappa, dot(lobe.mean, w)) * factor(w); },
      grid->quadrature(QuadratureLevels::kMaxLevel + 2));
  const OutwardFactors at_points = outward_factors(levels, a0, a1), means = outward_cell_means(levels, a0, a1);
  const std::vector<double> point_rule = lobe_cell_probabilities({lobe}, levels, 1e8, &at_points);
  const std::vector<double> mean_rule = lobe_cell_probabilities({lobe}, levels, 1e8, &means);
  int emptied_by_points = 0, emptied_by_means = 0;
  for (std::size_t c = 0; c < truth.size(); ++c) {
    emptied_by_points += truth[c] > 1e-7 && point_rule[c] == 0;
    emptied_by_means += truth[c] > 1e-7 && mean_rule[c] == 0;
  }
  EXPECT_GT(emptied_by_points, 0);
  EXPECT_EQ(emptied_by_means, 0);
  EXPECT_LT(tv(mean_rule, truth), tv(point_rule, truth));
}

// The lobes turned by `angle` about y, as a neighbouring bin's escapes are expected to lie.
std::vector<VmfLobe> turned(std::vector<VmfLobe> lobes, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  for (VmfLobe& l : lobes) l.mean = {c * l.mean.x + s * l.mean.z, l.mean.y, -s * l.mean.x + c * l.mean.z};
  return lobes;
}

// A bin pooled with two neighbours whose escapes are its own distribution turned by +-0.1 rad
// about y: from noise-free counts the pooled fit recovers the bin's lobes (so the turned
// deviance and its derivatives are right); from noisy ones it is closer to them than the fit
// of the bin alone (three times the escapes), and pooling without the turn, or turning the
// wrong way, is farther off than either.
TEST(VmfFit, NeighboursPooledAtTheirHeadingAddTheirEscapes) {
  auto grid = make_grid("healpix:8");
  QuadratureLevels levels(*grid);
  const std::vector<VmfLobe> truth = {{0.7, 120, normalize({0.3, 0, 0.95})}, {0.3, 15, normalize({0.6, 0.2, 0.8})}};
  const double angle = 0.1;
  CellQuadrature fine = grid->quadrature(QuadratureLevels::kMaxLevel + 1);
  const std::vector<double> exact = test::reference_cells(truth, fine);
  auto scaled = [](std::vector<double> p, double n) {
    for (double& v : p) v *= n;
    return p;
  };
  auto pooled_fit = [&](const std::vector<double>& own, const std::vector<double>& below,
                        const std::vector<double>& above, double turn) {
    VmfFitOptions o;
    o.pooled = {{&below, nullptr, -turn, 1.0}, {&above, nullptr, turn, 1.0}};
    return fit_vmf(own, levels, 2, o).lobes;
  };
  const double n = 1e6;
  const std::vector<double> own = scaled(exact, n);
  for (double turn : {angle, 0.8}) {
    const std::vector<double> below = scaled(test::reference_cells(turned(truth, -turn), fine), n),
                              above = scaled(test::reference_cells(turned(truth, turn), fine), n);
    EXPECT_LT(tv(test::reference_cells(pooled_fit(own, below, above, turn), fine), exact), 2e-3) << turn;
    // Noise-free counts: with exact derivatives Gauss-Newton converges as fast pooled as alone
    // (a turned deviance whose derivatives by the mean were not turned back takes 13
    // iterations at 0.8 rad against 4).
    VmfFitOptions o;
    o.pooled = {{&below, nullptr, -turn, 1.0}, {&above, nullptr, turn, 1.0}};
    EXPECT_LE(fit_vmf(own, levels, 2, o).iterations, fit_vmf(own, levels, 2).iterations + 2) << turn;
  }

  const std::vector<double> noisy = draw_histogram(truth, *grid, 3000, 11),
                            noisy_below = draw_histogram(turned(truth, -angle), *grid, 3000, 12),
                            noisy_above = draw_histogram(turned(truth, angle), *grid, 3000, 13);
  auto error = [&](const std::vector<VmfLobe>& lobes) { return tv(test::reference_cells(lobes, fine), exact); };
  const double alone = error(fit_vmf(noisy, levels, 2).lobes);
  const double pooled = error(pooled_fit(noisy, noisy_below, noisy_above, angle));
  const double unturned = error(pooled_fit(noisy, noisy_below, noisy_above, 0));
  const double backwards = error(pooled_fit(noisy, noisy_below, noisy_above, -angle));
  EXPECT_LT(pooled, 0.8 * alone);
  EXPECT_GT(unturned, alone);
  EXPECT_GT(backwards, unturned);
}

// A bin pooled with four neighbours (d = -2 .. 2) whose escapes follow its lobes continued
// linearly in alpha: the heavier lobe's log kappa grows by 0.25 per bin, the lighter lobe's
// logit by 0.4, and the lighter lobe turns by 0.05 rad per bin on top of the common heading
// (0.1 rad per bin). From noise-free counts a sloped pool recovers the bin's own lobes, with
// derivatives exact enough that Gauss-Newton converges about as fast as alone; a flat pool,
// which expects the neighbours to hold the bin's lobes as they are, is biased. From noisy
// counts (a few thousand escapes a bin) the sloped pool is closer to the bin's truth than the
// bin alone and than the flat pool.
TEST(VmfFit, SlopedPoolsFollowNeighboursThatChangeShape) {
  auto grid = make_grid("healpix:8");
  QuadratureLevels levels(*grid);
  CellQuadrature fine = grid->quadrature(QuadratureLevels::kMaxLevel + 1);
  const std::vector<VmfLobe> truth = {{0.7, 120, normalize({0.3, 0, 0.95})}, {0.3, 15, normalize({0.6, 0, 0.8})}};
  const double heading = 0.1;
  auto neighbour_lobes = [&](int d) {
    std::vector<VmfLobe> lobes = turned(truth, d * heading);
    lobes[0].kappa *= std::exp(0.25 * d);
    const double w1 = lobes[1].weight * std::exp(0.4 * d);
    lobes[1].weight = w1 / (lobes[0].weight + w1), lobes[0].weight = 1 - lobes[1].weight;
    lobes[1].mean = turned({lobes[1]}, 0.05 * d)[0].mean;
    return lobes;
  };
  const std::vector<double> exact = test::reference_cells(truth, fine);
  auto error = [&](const std::vector<VmfLobe>& lobes) { return tv(test::reference_cells(lobes, fine), exact); };
  auto pooled_fit = [&](const std::vector<double>& own, const std::vector<std::vector<double>>& near, bool sloped) {
    VmfFitOptions o;
    o.sloped = sloped;
    for (int d : {-2, -1, 1, 2}) o.pooled.push_back({&near[std::size_t(d + 2)], nullptr, d * heading, 1.0 - std::abs(d) / 3.0, d});
    return fit_vmf(own, levels, 2, o);
  };

  const double n = 1e6;
  std::vector<std::vector<double>> exact_near(5);
  for (int d = -2; d <= 2; ++d) {
    exact_near[std::size_t(d + 2)] = test::reference_cells(neighbour_lobes(d), fine);
    for (double& v : exact_near[std::size_t(d + 2)]) v *= n;
  }
  const std::vector<double>& own = exact_near[2];
  const VmfFitResult sloped = pooled_fit(own, exact_near, true);
  EXPECT_LT(error(sloped.lobes), 2e-3);
  EXPECT_GT(error(pooled_fit(own, exact_near, false).lobes), 10 * error(sloped.lobes));
  EXPECT_LE(sloped.iterations, fit_vmf(own, levels, 2).iterations + 4);

  std::vector<std::vector<double>> noisy_near(5);
  for (int d = -2; d <= 2; ++d) noisy_near[std::size_t(d + 2)] = draw_histogram(neighbour_lobes(d), *grid, 2000, 21 + std::uint64_t(d + 2));
  const double alone = error(fit_vmf(noisy_near[2], levels, 2).lobes);
  const double sloped_noisy = error(pooled_fit(noisy_near[2], noisy_near, true).lobes);
  const double flat_noisy = error(pooled_fit(noisy_near[2], noisy_near, false).lobes);
  EXPECT_LT(sloped_noisy, alone);
  EXPECT_LT(sloped_noisy, flat_noisy);
}

}  // namespace
}  // namespace stf::fit
