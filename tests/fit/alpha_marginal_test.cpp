// The alpha marginal smoothed across bins (fit/alpha_marginal.h): against a known density, in
// the limit of many counts, and against an independent table.
#include "alpha_marginal.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <numeric>
#include <random>

#include "stf/fit/fit_table.h"
#include "stf/precompute/precompute.h"
#include "seed.h"

namespace stf::fit {
namespace {

// A table frame with no walk behind it: 45 alpha bins of 8 equal-area sub-bins.
Table frame() {
  Table t;
  t.alpha_bins = 45, t.sub_bins = 8, t.once_tallied = true;
  for (int b = 0; b <= t.alpha_bins; ++b) t.alpha_edges.push_back(std::numbers::pi * b / t.alpha_bins);
  return t;
}

// The density per unit area exp(-4 alpha + 0.8 alpha^2) integrated over every sub-bin by the
// midpoint rule in cos(alpha) on 400 pieces (independent of the fit's Gauss-Legendre nodes),
// normalised to sum to 1.
std::vector<double> true_sub_shares(const Table& t) {
  std::vector<double> share;
  double total = 0;
  for (int b = 0; b < t.alpha_bins; ++b)
    for (int k = 0; k < t.sub_bins; ++k) {
      const double c0 = std::cos(t.alpha_edges[b]), c1 = std::cos(t.alpha_edges[b + 1]);
      const double lo = c0 + t.sub_edge(b, k) * (c1 - c0), hi = c0 + t.sub_edge(b, k + 1) * (c1 - c0);
      double s = 0;
      for (int i = 0; i < 400; ++i) {
        const double a = std::acos(lo + (hi - lo) * (i + 0.5) / 400);
        s += std::exp(-4 * a + 0.8 * a * a) * (lo - hi) / 400;
      }
      share.push_back(s), total += s;
    }
  for (double& s : share) s /= total;
  return share;
}

// Poisson counts of `expected` escapes in each half.
void draw_counts(Table& t, const std::vector<double>& share, double expected, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  for (int h = 0; h < 2; ++h) {
    t.multiple_sub_half[h].clear();
    for (double s : share) t.multiple_sub_half[h].push_back(double(std::poisson_distribution<long long>(expected * s)(rng)));
  }
}

// TV between bin masses (each normalised) and the truth's.
double bin_tv(const Table& t, const std::vector<double>& sub, const std::vector<double>& truth_sub) {
  double total = 0, tv = 0;
  for (double v : sub) total += v;
  for (int b = 0; b < t.alpha_bins; ++b) {
    double mass = 0, truth = 0;
    for (int k = 0; k < t.sub_bins; ++k) mass += sub[b * t.sub_bins + k], truth += truth_sub[b * t.sub_bins + k];
    tv += 0.5 * std::abs(mass / total - truth);
  }
  return tv;
}

std::vector<double> both_halves(const Table& t) {
  std::vector<double> c;
  for (std::size_t j = 0; j < t.multiple_sub_half[0].size(); ++j) c.push_back(t.multiple_sub_half[0][j] + t.multiple_sub_half[1][j]);
  return c;
}

// 30000 escapes, about what a 1e5-path table of a thin medium holds after two or more
// collisions: the smoothed bins are closer to the truth than the counts, in every one of 20
// draws, by a third on average; the total is the counts' own. With 1e9 escapes (no noise to
// speak of) nothing is lost: no bias floor, as the log density is a polynomial the spline holds.
TEST(AlphaMarginal, RecoversAKnownDensityFromPoissonCounts) {
  Table t = frame();
  const std::vector<double> truth = true_sub_shares(t);
  const std::uint64_t seed = test::test_seed(11);
  SCOPED_TRACE(test::seed_trace(seed));
  double raw_sum = 0, smooth_sum = 0;
  for (int draw = 0; draw < 20; ++draw) {
    draw_counts(t, truth, 15000, seed + draw);
    const std::vector<double> counts = both_halves(t);
    const AlphaMarginal m = smooth_alpha_marginal(t);
    ASSERT_EQ(int(m.bin_escapes.size()), t.alpha_bins);
    ASSERT_EQ(m.sub_escapes.size(), counts.size());
    double total = 0, smooth_total = 0;
    for (double c : counts) total += c;
    for (double e : m.bin_escapes) smooth_total += e;
    EXPECT_NEAR(smooth_total, total, 1e-9 * total);
    const double raw = bin_tv(t, counts, truth), smooth = bin_tv(t, m.sub_escapes, truth);
    EXPECT_LT(smooth, raw) << "draw " << draw;
    raw_sum += raw, smooth_sum += smooth;
  }
  EXPECT_LT(smooth_sum, 0.67 * raw_sum) << smooth_sum / 20 << " against " << raw_sum / 20;

  draw_counts(t, truth, 5e8, seed);
  const AlphaMarginal m = smooth_alpha_marginal(t);
  const double raw = bin_tv(t, both_halves(t), truth), smooth = bin_tv(t, m.sub_escapes, truth);
  // The counts' expected TV: E|n - N p| = sqrt(2 N p / pi) per bin, for N p large.
  double expected_raw = 0;
  for (int b = 0; b < t.alpha_bins; ++b) {
    double p = 0;
    for (int k = 0; k < t.sub_bins; ++k) p += truth[b * t.sub_bins + k];
    expected_raw += 0.5 * std::sqrt(2 * 1e9 * p / std::numbers::pi) / 1e9;
  }
  EXPECT_LT(smooth, raw);
  EXPECT_LT(smooth, expected_raw) << raw;
}

// No sub-bin tallies (older tables), or no escapes after two collisions in a half: nothing to
// smooth.
TEST(AlphaMarginal, EmptyWithoutSubBinsOrEscapes) {
  Table t = frame();
  const std::vector<double> zeros(std::size_t(t.alpha_bins * t.sub_bins), 0.0);
  t.multiple_sub_half = {zeros, zeros};
  EXPECT_TRUE(smooth_alpha_marginal(t).bin_escapes.empty());
  t.multiple_sub_half[0][5] = 3;  // one half alone cannot choose the roughness
  EXPECT_TRUE(smooth_alpha_marginal(t).bin_escapes.empty());
  t.multiple_sub_half[1][9] = 2;
  EXPECT_FALSE(smooth_alpha_marginal(t).bin_escapes.empty());
  t.sub_bins = 0;
  EXPECT_TRUE(smooth_alpha_marginal(t).bin_escapes.empty());
}

// A walked table of a thin forward medium (tau 1, g 0.9, 1e5 paths): the model's alpha marginal
// of the escapes after two or more collisions is closer to an independent 1e7-path table's than
// the counts it was fitted to; with FitSettings::smooth_alpha off it is the counts.
TEST(AlphaMarginal, ThinForwardModelMarginalCloserThanItsTable) {
  const Medium medium{0.95, 0.05, 0.9, 1};
  PrecomputeSettings s;
  s.grid = "healpix:4", s.alpha_bins = 45;
  s.paths = 100000, s.seed = 2;
  const Table small = *precompute(medium, s);
  s.paths = 10000000, s.seed = 1000;
  const Table reference = *precompute(medium, s);
  auto multiple = [](const Table& t) {  // per bin, per path launched
    std::vector<double> m(std::size_t(t.alpha_bins), 0.0);
    for (int h = 0; h < 2; ++h)
      for (std::size_t j = 0; j < t.multiple_sub_half[h].size(); ++j) m[j / std::size_t(t.sub_bins)] += t.multiple_sub_half[h][j] / double(t.paths);
    return m;
  };
  auto fitted = [&](bool smooth) {  // the model's, per path launched
    FitSettings f = parse_model_spec("vmf:2");
    f.smooth_alpha = smooth;
    FitReport r;
    const StfModel model = fit_table(small, f, &r);
    EXPECT_EQ(r.alpha_penalty >= 0, smooth);
    std::vector<double> m;
    const double rest = model.escape_probability * (1 - model.once_fraction);
    for (int b = 0; b < model.bins(); ++b)
      m.push_back(rest * model.alpha_probability[b] - (b == 0 ? std::exp(-medium.tau()) : 0.0));
    return m;
  };
  const std::vector<double> truth = multiple(reference), counts = multiple(small);
  auto tv = [&](const std::vector<double>& m) {
    double d = 0;
    for (std::size_t b = 0; b < m.size(); ++b) d += 0.5 * std::abs(m[b] - truth[b]);
    return d;
  };
  // Unsmoothed, the model's bins are the counts, scaled to the probability the fit estimates for
  // them all (fit_table, rest_probabilities): that differs from their plain share within 5 of its
  // binomial standard deviations.
  const std::vector<double> raw = fitted(false);
  const double share = std::accumulate(counts.begin(), counts.end(), 0.0), scale = std::accumulate(raw.begin(), raw.end(), 0.0) / share;
  EXPECT_NEAR(scale, 1, 5 * std::sqrt((1 - share) / (share * double(small.paths))));
  for (std::size_t b = 0; b < raw.size(); ++b) EXPECT_NEAR(raw[b], counts[b] * scale, 1e-12);
  const double smooth = tv(fitted(true));
  EXPECT_LT(smooth, 0.7 * tv(counts)) << smooth << " against " << tv(counts);
}

}  // namespace
}  // namespace stf::fit
