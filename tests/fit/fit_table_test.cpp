// Whole tables: stiff media, determinism, storage, evaluation.
#include "forget_checksum.h"
#include "fit_stages.h"
#include "stf/fit/fit_table.h"
#include "sh_fit.h"

#include <H5Cpp.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <mutex>
#include <numeric>
#include <random>

#include "stf/fit/alpha_tilt.h"
#include "stf/measure/evaluate.h"
#include "stf/core/grid.h"
#include "mirror.h"
#include "stf/fit/model_io.h"
#include "stf/precompute/precompute.h"
#include "stf/core/rng.h"
#include "seed.h"
#include "stf/once_scattered.h"
#include "stf/tilt.h"
#include "stf/measure/tolerance.h"

namespace stf::fit {
using namespace stf::measure;  // the measures of models (stf/measure/)
namespace {

Table make_table(Medium m, std::int64_t paths, const char* grid = "healpix:4", int bins = 18,
                 std::int64_t seed = 1, std::int64_t max_scatter = -1) {
  PrecomputeSettings s;
  s.paths = paths;
  s.grid = grid;
  s.alpha_bins = bins;
  s.seed = seed;
  s.max_scatter = max_scatter;
  return *precompute(m, s);
}

// Finite, normalised, and its direction density integrates to one in every bin.
void expect_sane(const StfModel& m, const char* what) {
  double alpha = 0;
  for (double p : m.alpha_probability) {
    ASSERT_TRUE(std::isfinite(p)) << what;
    alpha += p;
  }
  EXPECT_NEAR(alpha, 1, 1e-12) << what;
  EXPECT_TRUE(std::isfinite(m.escape_probability)) << what;
  auto grid = make_grid("healpix:8");
  const QuadratureLevels levels(*grid);
  for (int b = 0; b < m.bins(); ++b) {
    std::vector<double> p = smooth_cell_probabilities(m, b, levels);
    double s = 0;
    for (double v : p) {
      ASSERT_TRUE(std::isfinite(v)) << what << " bin " << b;
      s += v;
    }
    EXPECT_NEAR(s, 1, 1e-9) << what << " bin " << b;
    for (const VmfLobe& l : m.vmf) {
      ASSERT_TRUE(std::isfinite(l.kappa) && std::isfinite(l.weight) && std::isfinite(l.mean.z)) << what;
    }
    // The SH-derived pdf integrates to 1 over its own equal-area cells (one point per cell:
    // it is constant there).
    if (m.kind == ModelKind::kSh) {
      const int nz = m.sh_nz;
      double integral = 0;
      for (int r = 0; r < nz; ++r)
        for (int c = 0; c < 2 * nz; ++c) {
          double z = -1 + (2 * r + 1.0) / nz, phi = kPi * (c + 0.5) / nz, rho = std::sqrt(1 - z * z);
          integral += 4 * kPi / (2.0 * nz * nz) * m.direction_pdf(b, {rho * std::cos(phi), rho * std::sin(phi), z});
        }
      EXPECT_NEAR(integral, 1, 1e-6) << what << " bin " << b;
    }
  }
}

TEST(FitTable, StiffMediaGiveFiniteNormalisedModels) {
  struct Case {
    const char* what;
    Medium medium;
    std::int64_t paths, max_scatter;
  };
  const Case cases[] = {
      {"tau 1e-6 (delta)", {1e-6, 0, 0.5, 1}, 20000, -1},
      {"g = 0.999", {5, 0, 0.999, 1}, 20000, -1},
      {"g = -0.999", {5, 0, -0.999, 1}, 20000, -1},
      {"albedo 1e-6", {1e-6, 1, 0.3, 1}, 20000, -1},
      {"few paths: bins with 0 or 1 escape", {2, 0, 0.5, 1}, 40, -1},
      {"max-scatter 0", {3, 0, 0, 1}, 20000, 0},
      {"everything absorbed", {0, 50, 0, 1}, 2000, -1},
  };
  for (const Case& c : cases) {
    Table t = make_table(c.medium, c.paths, "healpix:4", 18, 1, c.max_scatter);
    for (const char* spec : {"vmf:2", "sh:6"}) {
      FitSettings s = parse_model_spec(spec);
      s.run.threads = 2;
      StfModel m = fit_table(t, s);
      expect_sane(m, (std::string(c.what) + " " + spec).c_str());
    }
  }
}

// The uncollided escapes are an exact delta of the model, not a fitted lobe: before, a lobe of
// kappa ~1e7 sat at a cell centre degrees off +z. The model cell probabilities put the delta
// exactly into the cell of +z, as the table has it.
TEST(FitTable, UncollidedEscapesAreAnExactDeltaNotALobe) {
  Table t = make_table({0.6, 0.1, 0.5, 1}, 100000, "healpix:8", 18);  // tau 0.7: half the escapes uncollided
  const double uncollided = t.uncollided_half[0] + t.uncollided_half[1];
  ASSERT_GT(uncollided, 0.3 * t.escaped_weight);
  for (const char* spec : {"vmf:4", "sh:8"}) {
    StfModel m = fit_table(t, parse_model_spec(spec));
    // Its probability is exact, e^{-tau} per path; the table's count agrees within its noise.
    EXPECT_NEAR(m.uncollided_probability() * m.escape_probability, std::exp(-t.medium.tau()), 1e-12) << spec;
    const double paths = double(t.paths), p0 = std::exp(-t.medium.tau());
    EXPECT_NEAR(uncollided, paths * p0, 5 * std::sqrt(paths * p0 * (1 - p0))) << spec;
    if (m.kind == ModelKind::kVmf) {
      for (int k = 0; k < m.lobes; ++k) EXPECT_LT(m.vmf[k].kappa, 1e5) << "bin 0 lobe " << k;
    }
    std::unique_ptr<DirectionGrid> grid = make_grid(t.grid);
    QuadratureLevels levels(*grid);
    const BinnedModel binned(m, t, *grid);
    SmoothCellCache smooth(m, levels);
    std::vector<double> p = binned.bin(0, std::ref(smooth)).second;
    const std::int64_t pole = grid->cell({0, 0, 1});
    double bin0 = 0;
    for (std::int64_t c = 0; c < t.cells; ++c) bin0 += t.weight_half[0][c] + t.weight_half[1][c];
    // The pole cell's table share against the model's: binomial noise of the bin's escapes.
    const double observed = (t.weight_half[0][pole] + t.weight_half[1][pole]) / bin0;
    EXPECT_NEAR(p[pole], observed, 5 * std::sqrt(observed * (1 - observed) / bin0) + 0.01) << spec;
  }
}

// HEALPix and the cube are symmetric under y -> -y: every cell's image is a cell of the same
// solid angle, whose centre is the image of the centre (the cube's to its projection's ~1e-6),
// and imaging twice is the identity.
TEST(Mirror, GridCellsHaveMirrorImages) {
  for (const char* spec : {"healpix:1", "healpix:2", "healpix:8", "healpix:16", "csc:3", "csc:8"}) {
    auto grid = make_grid(spec);
    const std::vector<std::int64_t> image = mirror_cells(*grid);
    ASSERT_EQ(std::int64_t(image.size()), grid->cell_count()) << spec;
    int fixed = 0;
    for (std::int64_t c = 0; c < grid->cell_count(); ++c) {
      const Vec3 x = grid->centre(c), y = grid->centre(image[std::size_t(c)]);
      EXPECT_NEAR(y.x, x.x, 1e-6) << spec;
      EXPECT_NEAR(y.y, -x.y, 1e-6) << spec;
      EXPECT_NEAR(y.z, x.z, 1e-6) << spec;
      EXPECT_EQ(image[std::size_t(image[std::size_t(c)])], c) << spec;
      fixed += image[std::size_t(c)] == c;
    }
    EXPECT_LT(fixed, grid->cell_count() / 2) << spec;
  }
}

// Folding a bin's counts averages each mirror pair of cells: the result is symmetric, keeps
// the bin's total, changes the noisy table and is a projection (folding again changes nothing).
TEST(Mirror, FoldingAveragesMirrorPairsAndKeepsTotals) {
  const Table t = make_table({2, 0.1, 0.5, 1}, 100000, "healpix:8", 18);
  auto grid = make_grid(t.grid);
  const std::vector<std::int64_t> image = mirror_cells(*grid);
  const std::size_t cells = std::size_t(t.cells);
  for (int b : {1, 5, 12}) {
    const std::vector<double> raw(t.weight_half[0].begin() + std::ptrdiff_t(b * cells),
                                  t.weight_half[0].begin() + std::ptrdiff_t((b + 1) * cells));
    std::vector<double> folded = raw;
    fold_over_mirror(folded, image);
    double sum_raw = 0, sum_folded = 0;
    int changed = 0;
    for (std::size_t c = 0; c < cells; ++c) {
      sum_raw += raw[c], sum_folded += folded[c];
      EXPECT_EQ(folded[c], folded[std::size_t(image[c])]) << "bin " << b << " cell " << c;
      EXPECT_EQ(folded[c], 0.5 * (raw[c] + raw[std::size_t(image[c])]));
      changed += folded[c] != raw[c];
    }
    EXPECT_EQ(sum_folded, sum_raw) << "bin " << b;
    EXPECT_GT(changed, 0) << "bin " << b;
    std::vector<double> twice = folded;
    fold_over_mirror(twice, image);
    EXPECT_EQ(twice, folded);
  }
}

// What folding, pooling, blends by bin and turning bins buy, judged against independent
// references, are single-seed measurements: bench/fit_regression.py.

// Sloped pools turn by headings smoothed across alpha (smooth_headings): a local quadratic
// reproduces a quadratic exactly, unwraps headings that cross +-pi, keeps a bin's own where its
// window has too few bins with escapes, and takes out most of the noise of sparse bins.
TEST(FitTable, SmoothedHeadingsKeepTheTrendAndQuietTheNoise) {
  const int bins = 45;
  std::vector<double> truth, escapes;
  for (int b = 0; b < bins; ++b) {
    truth.push_back(0.1 + 0.08 * b - 0.0007 * b * b);
    escapes.push_back(5000 * std::exp(-0.15 * b) + 5);
  }
  std::vector<double> slopes;
  std::vector<double> smooth = smooth_headings(truth, escapes, &slopes);
  for (int b = 0; b < bins; ++b) EXPECT_NEAR(smooth[b], truth[b], 1e-12) << b;
  for (int b = 0; b < bins; ++b) EXPECT_NEAR(slopes[b], 0.08 - 0.0014 * b, 1e-12) << b;  // the quadratic's derivative

  std::vector<double> wrapped;
  for (int b = 0; b < bins; ++b) wrapped.push_back(std::remainder(2.9 + 0.05 * b, 2 * kPi));
  ASSERT_LT(wrapped.back(), 0);  // crossed +-pi
  smooth = smooth_headings(wrapped, escapes);
  for (int b = 0; b < bins; ++b) EXPECT_NEAR(smooth[b] - smooth[0], 0.05 * b, 1e-9) << b;

  // An empty bin (heading atan2(0, 0) = 0) where the headings cross +-pi breaks no unwrapping.
  std::vector<double> gap = wrapped, sparse = escapes;
  int cross = 0;
  while (gap[cross + 1] > 0) ++cross;
  gap[cross + 1] = 0, sparse[cross + 1] = 0;
  smooth = smooth_headings(gap, sparse);
  for (int b = 0; b < bins; ++b)
    if (b != cross + 1) {
      EXPECT_NEAR(smooth[b] - smooth[0], 0.05 * b, 1e-9) << b;
    }

  std::vector<double> lone(bins, 0.0);
  lone[10] = lone[30] = 100;
  smooth = smooth_headings(wrapped, lone);
  EXPECT_NEAR(std::remainder(smooth[10] - wrapped[10], 2 * kPi), 0, 1e-12);

  // Each heading off by Gaussian noise of 1 / sqrt(escapes) radians (a spread of one radian):
  // the escape-weighted mean square error falls by more than half, over 20 draws.
  const std::uint64_t seed = test::test_seed(5);
  SCOPED_TRACE(test::seed_trace(seed));
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  double raw = 0, smoothed = 0;
  for (int draw = 0; draw < 20; ++draw) {
    std::vector<double> noisy;
    for (int b = 0; b < bins; ++b) noisy.push_back(truth[b] + normal(rng) / std::sqrt(escapes[b]));
    smooth = smooth_headings(noisy, escapes);
    for (int b = 0; b < bins; ++b) {
      raw += escapes[b] * (noisy[b] - truth[b]) * (noisy[b] - truth[b]);
      smoothed += escapes[b] * (smooth[b] - truth[b]) * (smooth[b] - truth[b]);
    }
  }
  EXPECT_LT(smoothed, 0.5 * raw) << smoothed / raw;
}

// --model auto is what the project recommends: hemispherical lobes at their held-out size; its
// model is hvmf:auto's.
TEST(FitTable, AutoIsHemisphericalLobesAtTheirHeldOutSize) {
  EXPECT_THROW(parse_model_spec("auto:3"), std::invalid_argument);
  const Table t = make_table({4, 0.5, 0.3, 1}, 40000, "healpix:4", 9);
  FitReport a, h;
  const StfModel by_auto = fit_table(t, parse_model_spec("auto"), &a);
  const StfModel by_hvmf = fit_table(t, parse_model_spec("hvmf:auto"), &h);
  EXPECT_TRUE(by_auto.kind == ModelKind::kVmf && by_auto.hemispherical);
  EXPECT_GT(a.candidates.size(), 1u);  // sizes chosen on the held-out half
  EXPECT_EQ(a.chosen_size, h.chosen_size);
  ASSERT_EQ(by_auto.vmf.size(), by_hvmf.vmf.size());
  for (std::size_t i = 0; i < by_auto.vmf.size(); ++i) EXPECT_EQ(by_auto.vmf[i].kappa, by_hvmf.vmf[i].kappa) << i;
}

// The fit tells its progress step by step, every step to its last bin, from the worker threads,
// and telling it changes nothing.
TEST(FitTable, ProgressTellsEveryStepToItsLastBin) {
  const Table t = make_table({4, 0.5, 0.3, 1}, 40000, "healpix:4", 9);
  FitSettings s = parse_model_spec("auto");
  s.run.threads = 2;
  std::mutex mutex;
  std::vector<std::string> order;         // the steps as they began
  std::map<std::string, std::int64_t> last, bins;  // each step's highest bin count told, and its bins
  s.run.progress = [&](std::string_view told, std::int64_t done, std::int64_t n) {
    std::lock_guard<std::mutex> lock(mutex);
    const std::string step(told);
    if (!last.count(step)) order.push_back(step);
    last[step] = std::max(last[step], done), bins[step] = n;
  };
  FitReport r;
  const StfModel told = fit_table(t, s, &r);
  for (const auto& [step, done] : last) EXPECT_EQ(done, bins[step]) << step;
  const std::string final_fit = "final fit, size " + std::to_string(r.chosen_size);
  ASSERT_GE(order.size(), 4u);
  EXPECT_EQ(order.front(), "fits, size 1, half 0");
  EXPECT_EQ(order[1], "held-out scores, size 1");
  EXPECT_EQ(order[order.size() - 2], final_fit);
  EXPECT_EQ(order.back(), "diagnostics");
  s.run.progress = nullptr;
  const StfModel untold = fit_table(t, s);
  ASSERT_EQ(told.vmf.size(), untold.vmf.size());
  for (std::size_t i = 0; i < told.vmf.size(); ++i) {
    EXPECT_EQ(told.vmf[i].kappa, untold.vmf[i].kappa) << i;
    EXPECT_EQ(told.vmf[i].weight, untold.vmf[i].weight) << i;
  }
}

// The once-scattered escapes are an exact part too: their probability is the one-collision
// quadrature's (the table's count agrees within its noise), and the fit sees only the escapes
// after two or more collisions. Limits: albedo 0 and --max-scatter 0 leave no such part, a
// vanishing tau leaves only the uncollided delta.
TEST(FitTable, OnceScatteredEscapesAreAnExactPartNotFitted) {
  const Medium medium{0.9, 0.1, 0.3, 1};
  Table t = make_table(medium, 100000, "healpix:4", 18);
  const double paths = double(t.paths), once = medium.albedo() * once_scattered_probability(medium.tau(), medium.g);
  ASSERT_GT(t.once_weight(), 0.2 * t.escaped_weight);
  EXPECT_NEAR(t.once_weight(), paths * once, 5 * std::sqrt(paths * once * (1 - once)));
  FitReport r;
  StfModel m = fit_table(t, parse_model_spec("vmf:3"), &r);
  EXPECT_NEAR(m.once_fraction * m.escape_probability, once, 1e-12);
  const double collided_twice = t.escaped_weight - t.uncollided_half[0] - t.uncollided_half[1] - t.once_weight();
  // The rest of the escape probability is estimated apart (OtherOutcomesTakeTheExactParts...):
  // within its plain share's binomial noise.
  const double exact = std::exp(-medium.tau()) + once, share = collided_twice / paths;
  EXPECT_NEAR(m.escape_probability, exact + share, 5 * std::sqrt(share * (1 - share) / paths));
  EXPECT_NEAR(m.escape_probability + m.absorbed_fraction + m.truncated_fraction, 1.0, 1e-12);
  double fitted = 0;
  for (const BinDiagnostics& d : r.bins) fitted += d.escapes;
  EXPECT_EQ(fitted, collided_twice);

  struct Limit {
    Medium medium;
    std::int64_t max_scatter;
    const char* what;
  };
  for (Limit c : {Limit{{0, 2, 0.3, 1}, -1, "albedo 0"}, Limit{{1.5, 0.5, 0.3, 1}, 0, "max_scatter 0"},
                  Limit{{1e-6, 0, 0.3, 1}, -1, "tau 1e-6"}}) {
    Table l = make_table(c.medium, 20000, "healpix:4", 18, 1, c.max_scatter);
    EXPECT_EQ(l.once_weight(), 0) << c.what;
    StfModel lm = fit_table(l, parse_model_spec("vmf:2"));
    EXPECT_LT(lm.once_fraction, 2e-6) << c.what;
    EXPECT_NEAR(lm.uncollided_probability() * lm.escape_probability, std::exp(-c.medium.tau()), 1e-12) << c.what;
    // The probabilities sum to 1 in the limits too.
    EXPECT_NEAR(lm.escape_probability + lm.absorbed_fraction + lm.truncated_fraction, 1.0, 1e-12) << c.what;
    if (c.medium.tau() < 1e-3) {
      EXPECT_GT(lm.uncollided_probability(), 1 - 2e-6) << c.what;
    }
  }
}

// The walk's other outcomes take their probabilities given the exact singular parts, and
// absorption by regression on three control variates (fit_table.cpp, rest_probabilities). Over
// 100 tables of 4000 paths per medium: they sum to 1 with the exact parts; the absorbed and the
// fitted escapes' probabilities are unbiased to O(1/n) (means within 4.5 standard errors and 2 / n
// of the same estimates from a 4e6-path table: the regression's coefficients come from the
// totals they correct, a bias of about -0.9 / n measured over media and sizes, which at 4000
// paths is up to 0.8 of a table's standard deviation and 8 of the mean's standard error); and
// the absorbed fraction's variance is below `bound` times that of the plain share, the fitted
// escapes' in the thin medium below 0.01 times. The bounds are
// twice the mean ratios over four other sets of 100 seeds (absorbed: thin 0.015, tau 8 at
// albedo 0.999 0.049, albedo 0.5 0.40; fitted escapes, thin: 0.0041, where the conditional
// share alone gives 0.23); the sets spread by less than 1.4x about their mean.
TEST(FitTable, OtherOutcomesTakeTheExactPartsAndTheCollisionCount) {
  struct Case {
    Medium medium;
    double bound;
  };
  for (const Case& c : {Case{{0.95, 0.05, 0.9, 1}, 0.03}, Case{{7.992, 0.008, 0.85, 1}, 0.1},
                        Case{{2, 2, 0.3, 1}, 0.8}}) {
    const Medium& medium = c.medium;
    const double exact = std::exp(-medium.tau()) + medium.albedo() * once_scattered_probability(medium.tau(), medium.g);
    auto fitted_share = [](const Table& t) {
      return (t.escaped_weight - t.uncollided_half[0] - t.uncollided_half[1] - t.once_weight()) / double(t.paths);
    };
    FitSettings f = parse_model_spec("vmf:1");
    f.smooth_alpha = false;
    const StfModel big = fit_table(make_table(medium, 4000000, "healpix:2", 9, 999), f);
    const double fitted_truth = big.escape_probability - exact, absorbed_truth = big.absorbed_fraction;
    std::vector<double> fitted, absorbed, fitted_plain, absorbed_plain;
    for (std::int64_t seed = 1; seed <= 100; ++seed) {
      const Table t = make_table(medium, 4000, "healpix:2", 9, seed);
      const StfModel m = fit_table(t, f);
      ASSERT_NEAR(m.escape_probability + m.absorbed_fraction + m.truncated_fraction, 1.0, 1e-12) << seed;
      fitted.push_back(m.escape_probability - exact);
      absorbed.push_back(m.absorbed_fraction);
      fitted_plain.push_back(fitted_share(t));
      absorbed_plain.push_back(t.absorbed_weight / double(t.paths));
    }
    auto mean = [](const std::vector<double>& x) { return std::accumulate(x.begin(), x.end(), 0.0) / double(x.size()); };
    auto variance = [&](const std::vector<double>& x) {
      const double m = mean(x);
      double v = 0;
      for (double e : x) v += (e - m) * (e - m);
      return v / double(x.size() - 1);
    };
    // The big table's estimate has the small ones' variance over 1000 (its own bias is 1e-3 of theirs).
    auto allowed = [&](const std::vector<double>& x) { return 4.5 * std::sqrt(variance(x) / 100 + variance(x) / 1000) + 2.0 / 4000; };
    const double tau = medium.tau();
    EXPECT_NEAR(mean(absorbed), absorbed_truth, allowed(absorbed)) << tau;
    EXPECT_NEAR(mean(fitted), fitted_truth, allowed(fitted)) << tau;
    EXPECT_LT(variance(absorbed), c.bound * variance(absorbed_plain))
        << tau << ": " << variance(absorbed) << " against " << variance(absorbed_plain);
    if (tau == 1) {
      EXPECT_LT(variance(fitted), 0.01 * variance(fitted_plain)) << variance(fitted) << " against " << variance(fitted_plain);
    }
  }
}

// A table without the absorbed paths' collisions (written before stf tallied them) takes its
// absorption as its share of the paths left after the exact singular parts, times 1 - p0 - p1.
TEST(FitTable, TablesWithoutTheAbsorbedCollisionsTakeTheConditionalShare) {
  const Medium medium{0.95, 0.05, 0.9, 1};
  Table t = make_table(medium, 20000, "healpix:2", 9);
  t.absorbed_collisions = -1;
  const StfModel m = fit_table(t, parse_model_spec("vmf:1"));
  const double p0 = std::exp(-medium.tau()), p1 = medium.albedo() * once_scattered_probability(medium.tau(), medium.g);
  const double rest = double(t.paths) - t.uncollided_half[0] - t.uncollided_half[1] - t.once_weight();
  EXPECT_NEAR(m.absorbed_fraction, (1 - p0 - p1) * t.absorbed_weight / rest, 1e-15);
  EXPECT_NEAR(m.escape_probability + m.absorbed_fraction + m.truncated_fraction, 1.0, 1e-12);
}

// When no path is left after the exact parts, nothing tallied can carry the rest 1 - p0 - p1: it
// is booked as absorbed, and the probabilities still sum to 1 (before, the rest was lost: at
// tau 1e-3 and albedo 0.5 the sum fell short by 5e-4).
TEST(FitTable, NoPathLeftAfterTheExactPartsBooksTheRestAsAbsorbed) {
  const Medium medium{5e-4, 5e-4, 0.3, 1};
  const Table t = make_table(medium, 100, "healpix:2", 9, 3);
  ASSERT_EQ(t.uncollided_half[0] + t.uncollided_half[1] + t.once_weight(), double(t.paths));  // this seed's walk
  const StfModel m = fit_table(t, parse_model_spec("vmf:1"));
  const double rest = 1 - std::exp(-medium.tau()) - medium.albedo() * once_scattered_probability(medium.tau(), medium.g);
  EXPECT_GT(rest, 4e-4);
  EXPECT_NEAR(m.absorbed_fraction, rest, 1e-15);
  EXPECT_NEAR(m.escape_probability + m.absorbed_fraction + m.truncated_fraction, 1.0, 1e-12);
}

// Tables written before the once-scattered escapes were tallied apart still fit, as before:
// with no once-scattered part and the tallied uncollided share.
// The tilt's maximum likelihood from sub-bin counts: exact on expected counts; on multinomial
// counts within 4.5 standard errors (Fisher information) of the truth.
TEST(AlphaTilt, FitRecoversTheTilt) {
  const std::vector<double> edges = {0, 0.1, 0.25, 0.3, 0.5, 0.8, 1};  // unequal parts
  std::uint64_t state = 91;
  for (double tilt : {-6.0, -0.8, 0.0, 0.4, 3.0}) {
    std::vector<double> p, expected;
    for (std::size_t k = 0; k + 1 < edges.size(); ++k) p.push_back(tilt_mass(tilt, edges[k], edges[k + 1]));
    for (double q : p) expected.push_back(1e4 * q);
    EXPECT_NEAR(tilt_from_counts(edges, expected), tilt, 1e-5);
    const double n = 2000;
    std::vector<double> counts(p.size(), 0.0);
    for (int i = 0; i < int(n); ++i) {
      double u = double(splitmix64(state) >> 11) * 0x1p-53, below = 0;
      std::size_t k = 0;
      while (k + 1 < p.size() && u >= below + p[k]) below += p[k++];
      counts[k] += 1;
    }
    const double h = 1e-4;
    double information = 0;
    for (std::size_t k = 0; k < p.size(); ++k) {
      const double score = (std::log(tilt_mass(tilt + h, edges[k], edges[k + 1])) -
                            std::log(tilt_mass(tilt - h, edges[k], edges[k + 1]))) / (2 * h);
      information += n * p[k] * score * score;
    }
    EXPECT_NEAR(tilt_from_counts(edges, counts), tilt, 4.5 / std::sqrt(information)) << tilt;
  }
  EXPECT_EQ(tilt_from_counts(edges, std::vector<double>(6, 0.0)), 0);
  EXPECT_NEAR(tilt_from_counts(edges, {5, 0, 0, 0, 0, 0}), -kMaxTilt, 1e-3);  // all at the lower edge
}

// Grouping bins keeps every sub-bin count and turns its edges into fractions of the group.
TEST(AlphaTilt, GroupedBinsKeepTheirSubBins) {
  Table t = make_table({3, 0.3, 0.9, 1}, 100000, "healpix:2", 18);
  ASSERT_GT(t.sub_bins, 0);
  Table c = coarsen_table(t, 3, 0);
  ASSERT_EQ(c.sub_bins, 3 * t.sub_bins);
  for (int h = 0; h < 2; ++h) {
    double a = 0, b = 0;
    for (double v : t.multiple_sub_half[h]) a += v;
    for (double v : c.multiple_sub_half[h]) b += v;
    EXPECT_EQ(a, b);
  }
  for (int j = 0; j < c.alpha_bins; ++j) {
    EXPECT_EQ(c.sub_edge(j, 0), 0);
    EXPECT_NEAR(c.sub_edge(j, c.sub_bins), 1, 1e-12);
    for (int k = 0; k < c.sub_bins; ++k) EXPECT_LT(c.sub_edge(j, k), c.sub_edge(j, k + 1));
    // The second fine bin starts where the first one's area ends.
    EXPECT_NEAR(c.sub_edge(j, t.sub_bins), area_share(t, 3 * j, 3), 1e-12);
  }
  // Tilts of the grouped table: forward scattering crowds each group towards its lower edge.
  std::vector<double> tilts = fit_alpha_tilts(c);
  ASSERT_EQ(int(tilts.size()), c.alpha_bins);
  EXPECT_LT(tilts[0], 0);
}

TEST(FitTable, TablesWithoutTheOnceScatteredTallyStillFit) {
  Table t = make_table({0.9, 0.1, 0.3, 1}, 20000);
  const std::string path = ::testing::TempDir() + "/stf_old_table_" + std::to_string(::getpid()) + ".h5";
  write_table(t, path);
  {
    test::forget_checksum(path);
    H5::H5File f(path, H5F_ACC_RDWR);
    f.unlink("/escape/once_half");  // tables before the once-scattered tally had no sub-bins either
    f.unlink("/escape/multiple_sub_half");
  }
  Table old = read_table(path);
  std::remove(path.c_str());
  EXPECT_FALSE(old.once_tallied);
  EXPECT_TRUE(old.once.empty());
  EXPECT_EQ(old.sub_bins, 0);
  StfModel m = fit_table(old, parse_model_spec("vmf:2"));
  EXPECT_EQ(m.once_fraction, 0);
  EXPECT_TRUE(m.alpha_tilt.empty());
  EXPECT_DOUBLE_EQ(m.escape_probability, old.escaped_weight / double(old.paths));
  EXPECT_DOUBLE_EQ(m.uncollided_fraction, (old.uncollided_half[0] + old.uncollided_half[1]) / old.escaped_weight);
}

// A model file of an older format is refused in one line naming its version and the fix.
TEST(FitTable, OlderModelsAreRefusedNamingTheFix) {
  Table t = make_table({2, 0.2, 0.5, 1}, 20000);
  FitReport report;
  StfModel m = fit_table(t, parse_model_spec("vmf:2"), &report);
  const std::string path = ::testing::TempDir() + "/stf_v5_model_" + std::to_string(::getpid()) + ".h5";
  Provenance provenance;
  provenance.table = &t;
  write_model(m, report, provenance, path);
  EXPECT_EQ(read_model(path).vmf.size(), m.vmf.size());
  {
    test::forget_checksum(path);
    H5::H5File f(path, H5F_ACC_RDWR);
    f.removeAttr("format_version");
    int five = 5;
    f.createAttribute("format_version", H5::PredType::NATIVE_INT, H5::DataSpace()).write(H5::PredType::NATIVE_INT, &five);
  }
  try {
    read_model(path);
    ADD_FAILURE() << "an older model was read";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("format_version 5 is older"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("stf fit"), std::string::npos) << e.what();
  }
  std::remove(path.c_str());
}

TEST(FitTable, EmptyBinsBorrowFromTheirNeighbours) {
  Table t = make_table({2, 0, 0.5, 1}, 300);  // some bins above 10 escapes, most below
  StfModel m = fit_table(t, parse_model_spec("vmf:1"));
  int borrowed = 0;
  for (int b = 0; b < m.bins(); ++b) {
    if (m.status[b] != BinStatus::kBorrowed) continue;
    ++borrowed;
    bool same_as_a_fitted_bin = false;
    for (int f = 0; f < m.bins(); ++f)
      if (m.status[f] == BinStatus::kFitted && m.vmf[f].kappa == m.vmf[b].kappa) same_as_a_fitted_bin = true;
    EXPECT_TRUE(same_as_a_fitted_bin) << b;
  }
  EXPECT_GT(borrowed, 0);
}

TEST(FitTable, DeterministicForAnyThreadCount) {
  Table t = make_table({4, 0.5, 0.6, 1}, 50000);
  for (const char* spec : {"vmf:3", "sh:8"}) {
    FitSettings s = parse_model_spec(spec);
    s.run.threads = 1;
    StfModel one = fit_table(t, s);
    s.run.threads = 3;
    StfModel three = fit_table(t, s);
    ASSERT_EQ(one.vmf.size(), three.vmf.size());
    for (std::size_t i = 0; i < one.vmf.size(); ++i) {
      EXPECT_EQ(one.vmf[i].weight, three.vmf[i].weight);
      EXPECT_EQ(one.vmf[i].kappa, three.vmf[i].kappa);
      EXPECT_EQ(one.vmf[i].mean.x, three.vmf[i].mean.x);
    }
    EXPECT_EQ(one.sh, three.sh);
  }
}

TEST(FitTable, StoreLoadRoundTripIsExact) {
  Table t = make_table({4, 0.5, 0.6, 1}, 30000);
  std::string path = ::testing::TempDir() + "/model_" + std::to_string(::getpid()) + ".h5";
  for (const char* spec : {"vmf:2", "sh:6", "sh:6 across alpha", "hvmf:auto", "lvmf:auto"}) {
    FitReport report;
    const std::string name = spec;
    FitSettings settings = parse_model_spec(name.substr(0, name.find(' ')));
    if (name.find(' ') != std::string::npos) settings.alpha_degree = 5;
    StfModel m = fit_table(t, settings, &report);
    if (name == "vmf:2") {  // widths of its own in every bin, as fits of thin forward media give
      m.alpha_blend = 2;
      for (int b = 0; b < m.bins(); ++b) m.alpha_blend_width.push_back(b % 3);
    }
    Provenance provenance;
    provenance.model_spec = spec, provenance.source_table = "table.h5", provenance.table = &t;
    write_model(m, report, provenance, path);
    StfModel r = read_model(path);
    EXPECT_EQ(r.alpha_probability, m.alpha_probability);
    EXPECT_EQ(r.alpha_edges, m.alpha_edges);
    EXPECT_EQ(r.escape_probability, m.escape_probability);
    EXPECT_EQ(r.sh, m.sh);
    EXPECT_EQ(r.sh_table, m.sh_table);
    EXPECT_EQ(r.alpha_degree, m.alpha_degree);
    EXPECT_EQ(r.sh_chebyshev, m.sh_chebyshev);
    EXPECT_EQ(r.alpha_tilt, m.alpha_tilt);
    EXPECT_FALSE(r.alpha_tilt.empty());
    EXPECT_EQ(r.alpha_blend, m.alpha_blend);
    EXPECT_EQ(r.alpha_blend_width, m.alpha_blend_width);
    EXPECT_EQ(r.alpha_turn, m.alpha_turn);
    EXPECT_EQ(r.alpha_turn.empty(), m.kind == ModelKind::kSh);  // vMF lobes turn with the exit point
    EXPECT_EQ(r.hemispherical, m.hemispherical);
    EXPECT_EQ(r.lifted, m.lifted);
    EXPECT_EQ(r.lifted, name == "lvmf:auto");
    EXPECT_EQ(r.packed_bytes(), m.packed_bytes());
    ASSERT_EQ(r.vmf.size(), m.vmf.size());
    for (std::size_t i = 0; i < m.vmf.size(); ++i) {
      EXPECT_EQ(r.vmf[i].kappa, m.vmf[i].kappa);
      EXPECT_EQ(r.vmf[i].mean.y, m.vmf[i].mean.y);
    }
    EXPECT_EQ(read_chi2_dof(path).size(), std::size_t(m.bins()));
  }
  std::remove(path.c_str());
}

TEST(Evaluate, TableAgainstItselfIsZero) {
  Table t = make_table({4, 0, 0.5, 1}, 20000);
  Evaluation e = evaluate(t, t);
  EXPECT_EQ(e.tv, 0);
  EXPECT_EQ(e.kl, 0);
}

// Two independent tables differ by sampling noise: TV ~ 1 / sqrt(paths) while most cells are
// populated. Quadrupling the paths should halve it (ratio 2 within 15%).
TEST(Evaluate, IndependentTablesConvergeLikeOneOverSqrtPaths) {
  const Medium m{3, 0, 0.3, 1};
  double tv_small = evaluate(make_table(m, 200000, "healpix:2", 9, 1), make_table(m, 200000, "healpix:2", 9, 2)).tv;
  double tv_large = evaluate(make_table(m, 800000, "healpix:2", 9, 3), make_table(m, 800000, "healpix:2", 9, 4)).tv;
  EXPECT_NEAR(tv_small / tv_large, 2.0, 0.3);
}

// Where the table is noisy (here ~1700 escapes per bin over 3072 cells), the fit is far
// closer to the reference than the table it came from, at a fraction of its bytes.
TEST(Evaluate, FittedModelBeatsItsRawTable) {
  const Medium m{5, 0, 0.5, 1};
  Table train = make_table(m, 30000, "healpix:16", 18, 1), reference = make_table(m, 3000000, "healpix:16", 18, 2);
  double raw = evaluate(train, reference).tv;
  for (const char* spec : {"vmf:3", "sh:8"}) {
    StfModel model = fit_table(train, parse_model_spec(spec));
    Evaluation e = evaluate(model, reference);
    EXPECT_LT(e.tv, raw) << spec;
    EXPECT_GT(e.model_bytes, 0);
    EXPECT_LT(e.model_bytes, e.table_bytes / 10) << spec;
  }
}

// A model of one narrow lobe per bin (tau 2, g 0.97) gives every cell some probability, however
// far from the lobe, so its KL against a table with escapes in those cells is finite.
TEST(Evaluate, NarrowLobesKeepAFiniteKl) {
  const Medium m{1.9, 0.1, 0.97, 1};
  const StfModel model = fit_table(make_table(m, 100000, "healpix:8", 30, 1), parse_model_spec("vmf:1"));
  const Evaluation e = evaluate(model, make_table(m, 300000, "healpix:8", 30, 2));
  EXPECT_TRUE(std::isfinite(e.kl)) << e.kl;
  EXPECT_GT(e.kl, 0);
}

TEST(Evaluate, RejectsMismatchedBins) {
  Table a = make_table({1, 0, 0, 1}, 1000, "healpix:2", 9), b = make_table({1, 0, 0, 1}, 1000, "healpix:2", 10);
  EXPECT_THROW(evaluate(a, b), std::invalid_argument);
  Table c = make_table({1, 0, 0, 1}, 1000, "csc:2", 9);
  EXPECT_THROW(evaluate(a, c), std::invalid_argument);
}

// A table whose bins hold draws from known mixtures (each half drawn independently): auto
// selection must not pick fewer lobes than the truth has, nor many more.
Table synthetic_table(const std::vector<VmfLobe>& truth, std::int64_t per_half, std::uint64_t seed) {
  Table t;
  t.medium = {1, 0, 0, 1};
  t.paths = 2 * per_half;
  t.escaped_weight = double(t.paths);
  t.grid = "healpix:8";
  t.alpha_bins = 3;
  auto grid = make_grid(t.grid);
  t.cells = grid->cell_count();
  t.solid_angle = grid->solid_angles();
  for (std::int64_t c = 0; c < t.cells; ++c) {
    const Vec3 d = grid->centre(c);
    t.direction.push_back({d.x, d.y, d.z});
  }
  for (int b = 0; b <= t.alpha_bins; ++b) t.alpha_edges.push_back(kPi * b / t.alpha_bins);
  std::uint64_t s = seed;
  auto u = [&] { return double(splitmix64(s) >> 11) * 0x1p-53; };
  for (auto& half : t.weight_half) {
    half.assign(std::size_t(t.alpha_bins) * t.cells, 0);
    for (int b = 0; b < t.alpha_bins; ++b)
      for (std::int64_t i = 0; i < per_half; ++i) {
        double pick = u();
        std::size_t k = 0;
        while (k + 1 < truth.size() && pick >= truth[k].weight) pick -= truth[k++].weight;
        half[std::size_t(b) * t.cells + grid->cell(sample_vmf(truth[k], u(), u()))] += 1;
      }
  }
  return t;
}

TEST(FitTable, AutoChoosesTheTruthsSizeWithinNoise) {
  std::vector<VmfLobe> one = {{1, 20, {0, 0, 1}}};
  std::vector<VmfLobe> three = {{0.5, 20, {0, 0, 1}}, {0.3, 40, {1, 0, 0}}, {0.2, 30, {0, -1, 0}}};
  FitReport r1, r3;
  // The truths are not mirror-symmetric, as exits are: the table is fitted as it is.
  FitSettings s = parse_model_spec("vmf:auto");
  s.fold_mirror = false;
  fit_table(synthetic_table(one, 20000, 7), s, &r1);
  fit_table(synthetic_table(three, 20000, 8), s, &r3);
  // The sweep stops after two sizes in a row that do not lower the lowest held-out NLL so far,
  // and not before.
  EXPECT_LT(r1.candidates.size(), auto_candidates(ModelKind::kVmf).size());
  for (const FitReport* r : {&r1, &r3}) {
    double lowest = std::numeric_limits<double>::infinity();
    int misses = 0;
    for (double nll : r->heldout_nll) {
      EXPECT_LT(misses, 2) << "a size tried after two in a row that gained nothing";
      if (nll < lowest) lowest = nll, misses = 0;
      else ++misses;
    }
    if (r->candidates.size() < auto_candidates(ModelKind::kVmf).size()) {
      EXPECT_EQ(misses, 2);
    }
  }
  EXPECT_EQ(r1.chosen_size, 1);
  EXPECT_GE(r3.chosen_size, 3);
  EXPECT_LE(r3.chosen_size, 4);
  FitReport sh;
  fit_table(synthetic_table(one, 20000, 9), parse_model_spec("sh:auto"), &sh);
  EXPECT_GE(sh.chosen_size, 4);  // a kappa = 20 lobe needs more than the dipole
}

// Coefficients that are polynomials of degree <= D in cos(alpha) come back exactly.
TEST(FitTable, AcrossAlphaChebyshevIsExactForPolynomials) {
  StfModel m;
  m.kind = ModelKind::kSh;
  m.band_limit = 2;
  m.sh_nz = 8;
  const int bins = 12, count = 9;
  for (int b = 0; b <= bins; ++b) m.alpha_edges.push_back(kPi * b / bins);
  m.alpha_probability.assign(bins, 1.0 / bins);
  m.status.assign(bins, BinStatus::kFitted);
  std::vector<double> escapes(bins);
  for (int b = 0; b < bins; ++b) {
    double x = std::cos(0.5 * (m.alpha_edges[b] + m.alpha_edges[b + 1]));
    escapes[b] = 100 + b;
    for (int i = 0; i < count; ++i) m.sh.push_back(i == 0 ? 0.28 : 0.01 * (i - 4 * x + 3 * x * x * x));
  }
  std::vector<double> original = m.sh;
  m.alpha_degree = 3;
  compress_across_alpha(m, escapes);
  ASSERT_EQ(m.sh_chebyshev.size(), std::size_t(4 * count));
  for (std::size_t i = 0; i < original.size(); ++i) EXPECT_NEAR(m.sh[i], original[i], 1e-12);
  EXPECT_LT(m.packed_bytes(), 128 + bins * 8 + 13 * 4 + 4 * count * 4 + 1);
}

// Each name --ablate takes turns off its own mechanism and no other: of the eight switches, the
// ablated settings differ from hvmf:auto's in exactly one, a different one for every name.
TEST(FitSettings, EachAblationTurnsOffItsOwnMechanism) {
  const auto switches = [](const FitSettings& s) {
    return std::vector<bool>{s.fold_mirror, s.pool_neighbours, s.wide_pools, s.smooth_alpha,
                             s.tilt,        s.turn,            s.max_blend > 0, s.blend_by_bin};
  };
  const FitSettings all = parse_model_spec("hvmf:auto");
  ASSERT_EQ(switches(all), std::vector<bool>(8, true));
  std::vector<int> times_off(8, 0);
  for (const Ablation& a : kAblations) {
    FitSettings s = all;
    ablate(s, a.name);
    const std::vector<bool> on = switches(s);
    EXPECT_EQ(std::count(on.begin(), on.end(), false), 1) << a.name;
    for (std::size_t i = 0; i < on.size(); ++i) times_off[i] += !on[i];
  }
  EXPECT_EQ(times_off, std::vector<int>(8, 1));
  FitSettings s = all;
  try {
    ablate(s, "turn,spin");
    ADD_FAILURE() << "an unknown name was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'spin'"), std::string::npos) << e.what();
  }
}

// The mechanisms fire where the study found them worth their place (docs/studies/
// 2026-12-ablation.md): on the thin forward medium (tau 1, g 0.9, albedo 0.95; 1e5 paths, seed 2,
// healpix:16 x 45 bins, as bench/fit_regression.py) hvmf:auto turns its bins at about the rate of
// the headings (1.66 from a 3e7-path table), pools every bin (sloped and wide pools both chosen),
// and blends, narrower near the axis than far from it. How much each buys is the bench's.
TEST(FitTable, MechanismsFireOnAThinForwardMedium) {
  const Table t = make_table({0.95, 0.05, 0.9, 1}, 100000, "healpix:16", 45, 2);
  FitReport r;
  const StfModel m = fit_table(t, parse_model_spec("hvmf:auto"), &r);
  ASSERT_EQ(m.alpha_turn.size(), 45u);
  for (int b = 0; b < 5; ++b) {
    EXPECT_GT(m.alpha_turn[std::size_t(b)], 1.2) << b;
    EXPECT_LT(m.alpha_turn[std::size_t(b)], 1.8) << b;
  }
  int sloped = 0, wide = 0;
  for (const PoolTry& p : r.pools) sloped += p.sloped, wide += p.width > 1 && !p.sloped;
  EXPECT_GT(sloped, 0);
  EXPECT_GT(wide, 0);
  EXPECT_GT(m.alpha_blend, 0);
  EXPECT_LT(m.blend_width(0), m.blend_width(20));
}

TEST(FitTable, ParsesModelSpecs) {
  EXPECT_EQ(parse_model_spec("vmf:4").size, 4);
  EXPECT_TRUE(parse_model_spec("sh:auto").automatic);
  for (const char* bad : {"", "vmf", "vmf:0", "vmf:17", "sh:33", "sh:-1", "gauss:3", "vmf:4x"})
    EXPECT_THROW(parse_model_spec(bad), std::invalid_argument) << bad;
}

}  // namespace
}  // namespace stf::fit
