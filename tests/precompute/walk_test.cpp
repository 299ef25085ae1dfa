// Physics of the walk against exact limits (docs/design.md, "Exact limits the tests check").
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numeric>

#include "chi2.h"
#include "stf/core/grid.h"
#include "stf/hg.h"
#include "stf/once_scattered.h"
#include "stf/precompute/precompute.h"
#include "seed.h"
#include "stf/precompute/walk.h"

namespace stf {
namespace {

Table run(const Medium& m, PrecomputeSettings s) {
  auto table = precompute(m, s);
  EXPECT_TRUE(table.has_value());
  return *table;
}

std::vector<double> alpha_marginal(const Table& t) {
  std::vector<double> w = t.weight(), marginal(t.alpha_bins, 0);
  for (int b = 0; b < t.alpha_bins; ++b)
    for (std::int64_t c = 0; c < t.cells; ++c) marginal[b] += w[b * t.cells + c];
  return marginal;
}

// Binomial count within 6 standard deviations of its mean.
void expect_binomial(double count, double n, double p, const char* what) {
  EXPECT_NEAR(count, n * p, 6 * std::sqrt(n * p * (1 - p)) + 1e-9) << what << " (p = " << p << ")";
}

TEST(Walk, WeightBookkeepingIsExact) {
  PrecomputeSettings s;
  s.paths = 200'000;
  s.alpha_bins = 18;
  s.grid = "healpix:4";
  s.max_scatter = 3;
  s.seed = test::test_seed(31);
  Table t = run({2, 1, 0.4, 1}, s);
  EXPECT_EQ(t.escaped_weight + t.absorbed_weight + t.truncated_weight, double(t.paths));
  std::vector<double> w = t.weight();
  EXPECT_EQ(std::accumulate(w.begin(), w.end(), 0.0), t.escaped_weight);
  double halves = std::accumulate(t.weight_half[1].begin(), t.weight_half[1].end(), 0.0);
  expect_binomial(halves, t.escaped_weight, 0.5, "odd-path half");
  EXPECT_GT(t.truncated_weight, 0);
  EXPECT_GT(t.absorbed_weight, 0);
}

// max_scatter = 0: a path either escapes without collision (probability exp(-tau)), at alpha
// = 0 heading +z, or is truncated at its first collision before absorption is decided.
TEST(Walk, NoCollisionLimitEscapesExpMinusTauAlongZ) {
  for (double tau : {0.1, 1.0, 3.0}) {
    PrecomputeSettings s;
    s.paths = 400'000;
    s.alpha_bins = 10;
    s.grid = "csc:3";
    s.max_scatter = 0;
    s.seed = test::test_seed(32);
    Table t = run({0.5 * tau, 0.5 * tau, 0.7, 1}, s);
    auto grid = make_grid(s.grid);
    std::vector<double> w = t.weight();
    double at_origin = w[grid->cell({0, 0, 1})];  // alpha bin 0, cell of +z
    EXPECT_EQ(at_origin, t.escaped_weight) << "every escape is at alpha = 0 along +z";
    EXPECT_EQ(t.absorbed_weight, 0);
    expect_binomial(t.escaped_weight, double(s.paths), std::exp(-tau), "uncollided escapes");
  }
}

TEST(Walk, AlbedoZeroLeavesOnlyTheUnscatteredEscape) {
  PrecomputeSettings s;
  s.paths = 400'000;
  s.alpha_bins = 10;
  s.grid = "healpix:2";
  s.seed = test::test_seed(33);
  Table t = run({0, 2, -0.3, 1}, s);
  auto grid = make_grid(s.grid);
  EXPECT_EQ(t.weight()[grid->cell({0, 0, 1})], t.escaped_weight);
  EXPECT_EQ(t.truncated_weight, 0);
  EXPECT_EQ(double(t.collisions), t.absorbed_weight);  // one collision each, all absorbing
  EXPECT_EQ(double(t.absorbed_collisions), t.absorbed_weight);
  expect_binomial(t.escaped_weight, double(s.paths), std::exp(-2.0), "uncollided escapes");
}

// The uncollided escapes are tallied apart (they are in the table's counts too): exactly the
// escapes of a --max-scatter 0 run, binomial with p = exp(-tau) in any medium.
TEST(Walk, UncollidedEscapesAreTalliedApart) {
  for (double tau : {1e-6, 0.5, 2.0}) {
    PrecomputeSettings s;
    s.paths = 200'000;
    s.alpha_bins = 12;
    s.grid = "healpix:4";
    s.seed = test::test_seed(34);
    Table t = run({0.8 * tau, 0.2 * tau, 0.4, 1}, s);
    const double uncollided = t.uncollided_half[0] + t.uncollided_half[1];
    expect_binomial(uncollided, double(s.paths), std::exp(-tau), "uncollided escapes");
    EXPECT_LE(uncollided, t.weight()[make_grid(s.grid)->cell({0, 0, 1})]);  // all in the +z cell of bin 0
  }
  // Albedo 0: nothing else escapes.
  PrecomputeSettings s;
  s.paths = 100'000;
  s.grid = "healpix:2";
  Table t = run({0, 1.5, 0.2, 1}, s);
  EXPECT_EQ(t.uncollided_half[0] + t.uncollided_half[1], t.escaped_weight);
}

// The exit distribution is symmetric under y' -> -y'. In a thin medium the once-scattered
// escapes lie exactly in the plane y' = 0, on cell boundaries: each cell against its mirror
// cell must agree within Poisson noise (a chi-square over the pairs).
TEST(Walk, ThinTablesAreMirrorSymmetric) {
  PrecomputeSettings s;
  s.paths = 400'000;
  s.alpha_bins = 18;
  s.grid = "healpix:8";
  s.seed = test::test_seed(35);
  Table t = run({1.0, 0.0, 0.5, 1}, s);  // tau 1: a third of the escapes scattered once
  auto grid = make_grid(s.grid);
  std::vector<double> w = t.weight();
  // The uncollided delta sits on the pole, a corner of four cells: not a density to mirror.
  w[grid->cell({0, 0, 1})] -= t.uncollided_half[0] + t.uncollided_half[1];
  double chi2 = 0;
  int pairs = 0;
  for (std::int64_t c = 0; c < t.cells; ++c) {
    Vec3 d = grid->centre(c);
    std::int64_t m = grid->cell({d.x, -d.y, d.z});
    if (m <= c) continue;  // each pair once; cells on the plane are their own mirror
    for (int b = 0; b < t.alpha_bins; ++b) {
      double x = w[b * t.cells + c], y = w[b * t.cells + m];
      if (x + y == 0) continue;
      chi2 += (x - y) * (x - y) / (x + y);
      ++pairs;
    }
  }
  ASSERT_GT(pairs, 500);
  // chi^2 of `pairs` degrees of freedom: mean pairs, sd sqrt(2 pairs).
  EXPECT_LT((chi2 - pairs) / std::sqrt(2.0 * pairs), 5) << "chi2 " << chi2 << " over " << pairs << " pairs";
}

// Gauss-Legendre nodes and weights on [-1, 1] (Newton on the Legendre recurrence).
void gauss_legendre(int n, std::vector<double>& x, std::vector<double>& w) {
  x.resize(n);
  w.resize(n);
  for (int i = 0; i < n; ++i) {
    double z = std::cos(kPi * (i + 0.75) / (n + 0.5)), dp = 0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = 0;
      for (int k = 1; k <= n; ++k) {
        double p2 = p1;
        p1 = p0;
        p0 = ((2 * k - 1) * z * p1 - (k - 1) * p2) / k;
      }
      dp = n * (z * p0 - p1) / (z * z - 1);
      double dz = p0 / dp;
      z -= dz;
      if (std::abs(dz) < 1e-15) break;
    }
    x[i] = z;
    w[i] = 2 / ((1 - z * z) * dp * dp);
  }
}

// Composite Gauss-Legendre of f over [a, b].
template <typename F>
double quadrature(F f, double a, double b, int panels = 32, int order = 20) {
  static std::vector<double> x, w;
  if (int(x.size()) != order) gauss_legendre(order, x, w);
  double sum = 0, h = (b - a) / panels;
  for (int p = 0; p < panels; ++p) {
    double lo = a + p * h;
    for (int i = 0; i < order; ++i) sum += 0.5 * h * w[i] * f(lo + 0.5 * h * (x[i] + 1));
  }
  return sum;
}

struct OneCollisionExact {
  std::vector<double> escaped_per_bin;  // fraction of paths escaping into each alpha bin
  double absorbed, truncated;
};

// max_scatter = 1 in the unit sphere: collision at depth s (density tau e^{-tau s}), survives
// with `albedo`, scatters to mu by HG, escapes after t(s, mu) with probability e^{-tau t} at
// cos(alpha) = s + t mu, or is truncated at its second collision. For fixed s the exit angle
// alpha grows as mu falls, and the mu aiming at the exit point of angle a is
// (cos a - s) / sqrt(1 - 2 s cos a + s^2); so each alpha bin is a mu interval and the integrand
// is smooth inside it.
OneCollisionExact one_collision_exact(double tau, double albedo, double g, int bins) {
  OneCollisionExact e;
  e.escaped_per_bin.assign(bins, 0);
  auto mu_towards = [](double a, double s) {
    double c = std::cos(a);
    return (c - s) / std::sqrt(1 - 2 * s * c + s * s);
  };
  auto exit_distance = [](double s, double mu) { return -s * mu + std::sqrt(1 - s * s * (1 - mu * mu)); };
  for (int b = 0; b < bins; ++b) {
    double a0 = kPi * b / bins, a1 = kPi * (b + 1) / bins;
    e.escaped_per_bin[b] = albedo * quadrature(
        [&](double s) {
          double inner = quadrature(
              [&](double mu) { return hg_pdf_mu(g, mu) * std::exp(-tau * exit_distance(s, mu)); },
              mu_towards(a1, s), mu_towards(a0, s), 8, 20);
          return tau * std::exp(-tau * s) * inner;
        },
        0, 1);
  }
  e.escaped_per_bin[0] += std::exp(-tau);  // uncollided
  double escaped = std::accumulate(e.escaped_per_bin.begin(), e.escaped_per_bin.end(), 0.0);
  e.absorbed = (1 - albedo) * (1 - std::exp(-tau));
  e.truncated = 1 - escaped - e.absorbed;
  return e;
}

TEST(Walk, OneCollisionMatchesExactQuadrature) {
  struct Case {
    double sigma_s, sigma_a, g;
  };
  for (Case c : {Case{1.5, 0.5, 0.3}, Case{0.6, 0.2, -0.5}, Case{4, 0, 0.8}}) {
    const int bins = 18;
    PrecomputeSettings s;
    s.paths = 2'000'000;
    s.alpha_bins = bins;
    s.grid = "healpix:1";
    s.max_scatter = 1;
    s.seed = test::test_seed(34);
    SCOPED_TRACE(test::seed_trace(std::uint64_t(s.seed)));
    Medium m{c.sigma_s, c.sigma_a, c.g, 1};
    Table t = run(m, s);
    OneCollisionExact e = one_collision_exact(m.tau(), m.albedo(), m.g, bins);
    // One multinomial over (alpha bins of escape, absorbed, truncated).
    std::vector<double> observed = alpha_marginal(t), expected = e.escaped_per_bin;
    observed.push_back(t.absorbed_weight);
    observed.push_back(t.truncated_weight);
    expected.push_back(e.absorbed);
    expected.push_back(e.truncated);
    for (double& x : expected) x *= double(s.paths);
    test::Chi2Result r = test::chi2_test(observed, expected);
    EXPECT_GT(r.p_value, test::kChi2Alpha) << "g = " << c.g << ": " << r.describe();
    expect_binomial(t.absorbed_weight, double(s.paths), e.absorbed, "absorbed");
    expect_binomial(t.truncated_weight, double(s.paths), e.truncated, "truncated");
  }
}

// The once-scattered escapes, tallied apart per (half, alpha bin, cell) while the walk goes on
// past them, against the one-collision quadrature: one multinomial over their alpha bins and
// everything else. They are part of the table's weight, cell by cell.
TEST(Walk, OnceScatteredEscapesAreTalliedApart) {
  const int bins = 18;
  PrecomputeSettings s;
  s.paths = 1'000'000;
  s.alpha_bins = bins;
  s.grid = "healpix:2";
  s.seed = test::test_seed(36);
  SCOPED_TRACE(test::seed_trace(std::uint64_t(s.seed)));
  for (Medium m : {Medium{1.2, 0.3, 0.3, 1}, Medium{0.2, 0.1, -0.7, 1}, Medium{3, 0, 0.9, 1}}) {
    Table t = run(m, s);
    OneCollisionExact e = one_collision_exact(m.tau(), m.albedo(), m.g, bins);
    e.escaped_per_bin[0] -= std::exp(-m.tau());
    std::vector<double> observed(bins + 1, 0.0), expected(bins + 1, 0.0);
    for (const auto& [key, w] : t.once) {
      ASSERT_LE(w, t.weight_half[key & 1][key >> 1]);
      observed[std::size_t((key >> 1) / std::uint64_t(t.cells))] += w;
    }
    observed[bins] = double(s.paths) - t.once_weight();
    for (int b = 0; b < bins; ++b) expected[b] = e.escaped_per_bin[b] * double(s.paths);
    expected[bins] = double(s.paths) * (1 - std::accumulate(e.escaped_per_bin.begin(), e.escaped_per_bin.end(), 0.0));
    test::Chi2Result r = test::chi2_test(observed, expected);
    EXPECT_GT(r.p_value, test::kChi2Alpha) << "g = " << m.g << ": " << r.describe();
    // The sampler library's probability of the part, from its own quadrature.
    expect_binomial(t.once_weight(), double(s.paths), m.albedo() * once_scattered_probability(m.tau(), m.g), "once");
  }
}

// The escapes after two or more collisions, counted in equal-area parts of coarse alpha bins,
// against an independent table (another seed) with 240 linear alpha bins. A fine bin lies in
// one part or straddles a part's edge; a part's count must lie between what the fine bins
// inside it and those touching it give, within 4.5 standard deviations of the two counts.
TEST(Walk, SubBinsMatchAFinerTable) {
  PrecomputeSettings s;
  s.paths = 1'000'000;
  s.grid = "healpix:1";
  s.seed = test::test_seed(37);
  SCOPED_TRACE(test::seed_trace(std::uint64_t(s.seed)));
  const Medium m{2.7, 0.3, 0.8, 1};
  s.alpha_bins = 3;
  const Table coarse = run(m, s);
  EXPECT_EQ(table_error(coarse), "");
  ASSERT_EQ(coarse.sub_bins, kSubBins);
  s.alpha_bins = 240;
  s.seed += 1;
  const Table fine = run(m, s);
  // Per fine bin: escapes less the once-scattered and uncollided ones.
  std::vector<double> multiple = alpha_marginal(fine);
  for (const auto& [key, w] : fine.once) multiple[std::size_t((key >> 1) / std::uint64_t(fine.cells))] -= w;
  multiple[0] -= fine.uncollided_half[0] + fine.uncollided_half[1];
  for (int b = 0; b < coarse.alpha_bins; ++b)
    for (int k = 0; k < kSubBins; ++k) {
      const double c0 = std::cos(coarse.alpha_edges[b]), c1 = std::cos(coarse.alpha_edges[b + 1]);
      const double hi = c0 - (c0 - c1) * k / kSubBins, lo = c0 - (c0 - c1) * (k + 1) / kSubBins;  // cos(alpha)
      double inside = 0, touching = 0;
      for (int j = 0; j < fine.alpha_bins; ++j) {
        const double f0 = std::cos(fine.alpha_edges[j]), f1 = std::cos(fine.alpha_edges[j + 1]);
        if (f1 >= lo - 1e-12 && f0 <= hi + 1e-12) inside += multiple[j];
        else if (f1 < hi && f0 > lo) touching += multiple[j];
      }
      const double count = coarse.multiple_sub_half[0][std::size_t(b * kSubBins + k)] +
                           coarse.multiple_sub_half[1][std::size_t(b * kSubBins + k)];
      const double sigma = std::sqrt(count + inside + touching);
      EXPECT_GE(count, inside - 4.5 * sigma) << "bin " << b << " part " << k;
      EXPECT_LE(count, inside + touching + 4.5 * sigma) << "bin " << b << " part " << k;
    }
}

// Only tau = sigma_t r matters. Scaling by 2 keeps tau bit-identical, and so the table; a
// factor 3 changes tau in its last bit, so the tables agree in distribution only.
TEST(Walk, ScaleInvariance) {
  PrecomputeSettings s;
  s.paths = 300'000;
  s.alpha_bins = 18;
  s.grid = "healpix:2";
  s.seed = test::test_seed(35);
  Table base = run({3, 1, 0.5, 0.5}, s);
  Table doubled = run({6, 2, 0.5, 0.25}, s);
  EXPECT_EQ(base.weight(), doubled.weight());
  EXPECT_EQ(base.absorbed_weight, doubled.absorbed_weight);

  s.seed += 1;  // an independent sample for the two-sample test
  Table tripled = run({9, 3, 0.5, 0.5 / 3}, s);
  test::Chi2Result r = test::chi2_two_sample(base.weight(), tripled.weight());
  EXPECT_GT(r.p_value, test::kChi2Alpha) << r.describe();
}

TEST(Walk, SameSeedSameTableForAnyThreadCount) {
  PrecomputeSettings s;
  s.paths = 300'001;  // not a multiple of the chunk size
  s.alpha_bins = 30;
  s.grid = "csc:5";
  s.seed = 77;
  std::vector<Table> tables;
  for (int threads : {1, 2, 3, 5}) {
    s.run.threads = threads;
    tables.push_back(run({5, 0.5, 0.6, 1}, s));
  }
  for (std::size_t i = 1; i < tables.size(); ++i) {
    EXPECT_EQ(tables[i].weight_half[0], tables[0].weight_half[0]);
    EXPECT_EQ(tables[i].weight_half[1], tables[0].weight_half[1]);
    EXPECT_EQ(tables[i].multiple_sub_half, tables[0].multiple_sub_half);
    EXPECT_EQ(tables[i].absorbed_weight, tables[0].absorbed_weight);
    EXPECT_EQ(tables[i].collisions, tables[0].collisions);
    EXPECT_EQ(tables[i].absorbed_collisions, tables[0].absorbed_collisions);
  }
  s.seed = 78;
  EXPECT_NE(run({5, 0.5, 0.6, 1}, s).weight(), tables[0].weight());
}

TEST(Walk, CancelStopsEarly) {
  std::atomic<bool> cancel{true};
  PrecomputeSettings s;
  s.paths = 100'000'000;
  s.run.cancel = &cancel;
  EXPECT_FALSE(precompute({100, 0, 0, 1}, s).has_value());
}

TEST(Walk, ValidateNamesTheOption) {
  PrecomputeSettings ok;
  EXPECT_FALSE(validate({1, 0, 0, 1}, ok).has_value());
  EXPECT_NE(validate({-1, 0, 0, 1}, ok)->find("--sigma-s"), std::string::npos);
  EXPECT_NE(validate({1, NAN, 0, 1}, ok)->find("--sigma-a"), std::string::npos);
  EXPECT_NE(validate({1, 0, 1, 1}, ok)->find("--g"), std::string::npos);
  EXPECT_NE(validate({1, 0, 0, 0}, ok)->find("--radius"), std::string::npos);
  EXPECT_NE(validate({0, 0, 0, 1}, ok)->find("--sigma-s"), std::string::npos);
  PrecomputeSettings bad = ok;
  bad.grid = "csc:0";
  EXPECT_NE(validate({1, 0, 0, 1}, bad)->find("--grid"), std::string::npos);
}

TEST(AlphaBins, SubBinsAreEqualAreaParts) {
  const AlphaBins bins(5);
  const double c0 = std::cos(kPi / 5), c1 = std::cos(2 * kPi / 5);
  for (int k = 0; k < kSubBins; ++k) {
    EXPECT_EQ(bins.sub_bin(c0 - (c0 - c1) * (k + 0.01) / kSubBins, 1), k);
    EXPECT_EQ(bins.sub_bin(c0 - (c0 - c1) * (k + 0.99) / kSubBins, 1), k);
  }
  EXPECT_EQ(bins.sub_bin(c0, 1), 0);
  EXPECT_EQ(bins.sub_bin(c1, 1), kSubBins - 1);
}

TEST(AlphaBins, MatchesLinearBinsInAlpha) {
  AlphaBins bins(90);
  for (int i = 0; i <= 10000; ++i) {
    double alpha = kPi * i / 10000;
    int expect = std::min(int(alpha / kPi * 90), 89);
    int got = bins.bin(std::cos(alpha));
    // Only points within rounding of an edge may land on its other side.
    if (got != expect) {
      EXPECT_NEAR(alpha * 90 / kPi, std::round(alpha * 90 / kPi), 1e-9);
    }
  }
  EXPECT_EQ(bins.bin(1.0), 0);
  EXPECT_EQ(bins.bin(-1.0), 89);
}

}  // namespace
}  // namespace stf

namespace {

// The walk's sparse once-scattered tally against a std::map: the same counts at the same keys
// through growth and colliding probes, and back after assign().
TEST(SparseCounts, CountsWhatAMapCounts) {
  stf::SparseCounts counts;
  std::map<std::uint64_t, double> reference;
  std::uint64_t state = 7;
  for (int i = 0; i < 200000; ++i) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    const std::uint64_t key = (state >> 33) % 5000 * 1024;  // multiples of 1024: hashes that collide
    counts.add(key);
    reference[key] += 1;
  }
  EXPECT_EQ(counts.sorted(), reference);
  stf::SparseCounts copy;
  copy.assign(reference);
  copy.add(3, 2);
  reference[3] += 2;
  EXPECT_EQ(copy.sorted(), reference);
}

}  // namespace
