// Tables stf did not make: the halves thinned from their counts, the grid recognised from
// their cells, and the file that holds only the four datasets.
#include "stf/core/minimal_table.h"

#include <H5Cpp.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "stf/core/files.h"
#include "stf/core/grid.h"
#include "stf/core/h5io.h"
#include "seed.h"

namespace stf {
namespace {

// Each count n of a Poisson(lambda) table splits into halves that are independent
// Poisson(lambda / 2): over many cells, their mean and variance are lambda / 2 and their
// correlation 0, within 4 standard errors (the statistics of m cells: the mean's standard error
// sqrt(lambda / 2 / m), the sample variance's sqrt(mu (1 + 2 mu) / m) for Poisson(mu = lambda / 2)
// (its fourth central moment less the squared variance, over m), the correlation's 1 / sqrt(m)).
TEST(MinimalTable, ThinnedHalvesOfPoissonCountsAreIndependentPoissonHalves) {
  const std::uint64_t seed = test::test_seed(31);
  SCOPED_TRACE(test::seed_trace(seed));
  std::mt19937_64 rng(seed);
  for (double lambda : {0.7, 12.0, 80.0}) {
    const int bins = 4, cells = 20000;
    std::poisson_distribution<int> poisson(lambda);
    std::vector<double> weight(std::size_t(bins) * cells);
    for (double& w : weight) w = poisson(rng);
    Table t;
    t.alpha_bins = bins, t.cells = cells;
    split_halves(weight, seed, t);
    ASSERT_EQ(t.halves, Halves::kThinned);
    const double m = double(weight.size());
    double mean[2] = {0, 0}, square[2] = {0, 0}, cross = 0;
    for (std::size_t i = 0; i < weight.size(); ++i) {
      ASSERT_EQ(t.weight_half[0][i] + t.weight_half[1][i], weight[i]);
      for (int h = 0; h < 2; ++h) mean[h] += t.weight_half[h][i] / m, square[h] += t.weight_half[h][i] * t.weight_half[h][i] / m;
      cross += t.weight_half[0][i] * t.weight_half[1][i] / m;
    }
    for (int h = 0; h < 2; ++h) {
      const double variance = square[h] - mean[h] * mean[h];
      EXPECT_NEAR(mean[h], lambda / 2, 4 * std::sqrt(lambda / 2 / m)) << "lambda " << lambda;
      EXPECT_NEAR(variance, lambda / 2, 4 * std::sqrt(lambda / 2 * (1 + lambda) / m)) << "lambda " << lambda;
    }
    const double correlation = (cross - mean[0] * mean[1]) /
                               std::sqrt((square[0] - mean[0] * mean[0]) * (square[1] - mean[1] * mean[1]));
    EXPECT_NEAR(correlation, 0, 4 / std::sqrt(m)) << "lambda " << lambda;
  }
}

// Binomial(n, 1/2) of large counts: mean n / 2 and variance n / 4 over many draws.
TEST(MinimalTable, BinomialHalfOfLargeCounts) {
  std::uint64_t state = test::test_seed(7);
  SCOPED_TRACE(test::seed_trace(state));
  const std::uint64_t n = 1001;
  const int draws = 20000;
  double mean = 0, square = 0;
  for (int i = 0; i < draws; ++i) {
    const double k = double(binomial_half(n, state));
    ASSERT_LE(k, double(n));
    mean += k / draws, square += k * k / draws;
  }
  EXPECT_NEAR(mean, n / 2.0, 4 * std::sqrt(n / 4.0 / draws));
  EXPECT_NEAR(square - mean * mean, n / 4.0, 4 * n / 4.0 * std::sqrt(2.0 / draws));
}

TEST(MinimalTable, HalvesAreReproducibleAndWeightsSplitEvenly) {
  Table a, b, w;
  a.alpha_bins = b.alpha_bins = w.alpha_bins = 2;
  a.cells = b.cells = w.cells = 3;
  const std::vector<double> counts{0, 5, 100, 7, 1, 3};
  split_halves(counts, 9, a);
  split_halves(counts, 9, b);
  EXPECT_EQ(a.weight_half, b.weight_half);
  split_halves({0, 0.5, 100, 7, 1, 3}, 9, w);
  EXPECT_EQ(w.halves, Halves::kEven);
  EXPECT_EQ(w.weight_half[0][1], 0.25);
  EXPECT_EQ(w.weight_half[1][1], 0.25);
}

TEST(MinimalTable, GridRecognisedFromItsCells) {
  EXPECT_EQ(grid_of_cells(768), "healpix:8");
  EXPECT_EQ(grid_of_cells(12), "healpix:1");
  EXPECT_EQ(grid_of_cells(6 * 45 * 45), "csc:45");
  EXPECT_EQ(grid_of_cells(100), "");
  EXPECT_EQ(grid_of_cells(12 * 9), "");  // NSIDE 3 is no power of two
  Table t;
  lay_out(t, *make_grid("healpix:4"), 3);
  EXPECT_EQ(grid_mismatch("healpix:4", t.direction), "");
  std::swap(t.direction[5], t.direction[6]);  // another numbering
  EXPECT_NE(grid_mismatch("healpix:4", t.direction).find("cell 5"), std::string::npos);
}

// A file of the four datasets alone reads as a table: paths the weights' sum, the grid from its
// cells, halves thinned, no medium.
TEST(MinimalTable, FourDatasetsAloneReadAsATable) {
  Table layout;
  lay_out(layout, *make_grid("healpix:2"), 5);
  std::vector<double> weight(std::size_t(layout.alpha_bins * layout.cells));
  for (std::size_t i = 0; i < weight.size(); ++i) weight[i] = double(i % 7);
  const std::string path = ::testing::TempDir() + "minimal_" + std::to_string(::getpid()) + ".h5";
  replace_file(path, minimal_table_file(layout, weight, [](H5::H5File&) {}));
  const Table t = read_table(path);
  std::remove(path.c_str());
  double total = 0;
  for (double w : weight) total += w;
  EXPECT_EQ(t.grid, "healpix:2");
  EXPECT_EQ(t.paths, std::int64_t(total));
  EXPECT_EQ(t.escaped_weight, total);
  EXPECT_EQ(t.absorbed_weight, 0);
  EXPECT_FALSE(t.has_medium());
  EXPECT_EQ(t.halves, Halves::kThinned);
  EXPECT_EQ(t.weight(), weight);
}

// A medium given with a NaN is refused: read as no medium, it would be dropped on the next write.
TEST(MinimalTable, ANonFiniteMediumIsRefused) {
  Table layout;
  lay_out(layout, *make_grid("healpix:2"), 5);
  const std::vector<double> weight(std::size_t(layout.alpha_bins * layout.cells), 1.0);
  const std::string path = ::testing::TempDir() + "nan_medium_" + std::to_string(::getpid()) + ".h5";
  replace_file(path, minimal_table_file(layout, weight, [](H5::H5File& f) {
                 h5::put_attr(f, "sigma_s", std::nan(""));
                 h5::put_attr(f, "sigma_a", 0.1);
                 h5::put_attr(f, "g", 0.0);
               }));
  try {
    read_table(path);
    ADD_FAILURE() << "a NaN sigma_s was read";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("finite"), std::string::npos) << e.what();
  }
  std::remove(path.c_str());
}

}  // namespace
}  // namespace stf
