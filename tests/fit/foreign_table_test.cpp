// Fits of tables stf did not make: the singular parts taken out from the medium, none without
// one, and fixed sizes only for weights without halves.
#include <gtest/gtest.h>

#include <cmath>

#include "stf/measure/evaluate.h"
#include "stf/fit/expected_singular.h"
#include "stf/fit/fit_table.h"
#include "stf/core/grid.h"
#include "stf/core/minimal_table.h"
#include "stf/fit/model_io.h"
#include "stf/precompute/precompute.h"
#include "stf/once_scattered.h"

namespace stf::fit {
using namespace stf::measure;  // the measures of models (stf/measure/)
namespace {

const Medium kMedium{1.8, 0.2, 0.5, 1};  // tau 2, albedo 0.9

// A walk's table as a file of its four datasets (and, with `medium`, the medium and paths)
// reads: thinned halves, no tallies of the singular parts.
Table foreign(const Table& walked, bool medium) {
  Table t = walked;
  split_halves(walked.weight(), 3, t);
  t.uncollided_half = {-1, -1};
  t.once.clear();
  t.once_tallied = false;
  t.sub_bins = 0;
  t.multiple_sub_half = {};
  t.collisions = 0, t.absorbed_collisions = -1;
  if (!medium) {
    const double none = std::nan("");
    t.medium = {none, none, none, none};
  }
  return t;
}

Table walked_table() {
  PrecomputeSettings s;
  s.paths = 40000, s.grid = "healpix:4", s.alpha_bins = 12, s.seed = 5;
  return *precompute(kMedium, s);
}

FitSettings fixed(const char* spec) {
  FitSettings s = parse_model_spec(spec);
  s.run.threads = 2;
  return s;
}

// With the medium known, the fitted model's uncollided and once-scattered probabilities per path
// are e^{-tau} and the one-collision quadrature's, to rounding, as from the walk's tallies.
TEST(ForeignTable, SingularPartsOfAKnownMediumAreExact) {
  const Table t = foreign(walked_table(), true);
  ASSERT_TRUE(wants_expected_singular_parts(t));
  FitReport report;
  const StfModel m = fit_table(t, fixed("vmf:2"), &report);
  EXPECT_EQ(report.singular_parts, "expected from the medium");
  EXPECT_EQ(report.heldout_halves, "thinned");
  const double tau = kMedium.tau(), rest = m.escape_probability * (1 - m.once_fraction);
  EXPECT_NEAR(m.uncollided_fraction * rest, std::exp(-tau), 1e-12);
  EXPECT_NEAR(m.once_fraction * m.escape_probability, kMedium.albedo() * once_scattered_probability(tau, kMedium.g), 1e-12);
  // Smoothed, bin 0's cell of +z holds at least the uncollided weight, and the weights add up
  // to the table's escapes.
  const std::vector<double> smoothed = expected_weights(m, t);
  double total = 0;
  for (double w : smoothed) total += w;
  EXPECT_NEAR(total, t.escaped_weight, 1e-9 * t.escaped_weight);
  const std::int64_t pole = make_grid(t.grid)->cell({0, 0, 1});
  EXPECT_GE(smoothed[std::size_t(pole)], t.escaped_weight * m.uncollided_fraction * (1 - m.once_fraction) * (1 - 1e-12));
}

TEST(ForeignTable, WithoutAMediumOnlyThePoleCellIsTakenOut) {
  const Table t = foreign(walked_table(), false);
  FitReport report;
  const StfModel m = fit_table(t, fixed("hvmf:2"), &report);
  EXPECT_EQ(report.singular_parts, "none but bin 0's cell of +z as the uncollided part");
  EXPECT_EQ(m.once_fraction, 0);
  // Bin 0's cell of +z is the uncollided delta: its weight, to rounding.
  const std::size_t pole = std::size_t(make_grid(t.grid)->cell({0, 0, 1}));
  EXPECT_NEAR(m.uncollided_fraction * t.escaped_weight, t.weight()[pole], 1e-9 * t.escaped_weight);
  EXPECT_FALSE(m.has_medium());
  EXPECT_EQ(model_error(m), "");
}

TEST(ForeignTable, WeightsWithoutHalvesFitFixedSizesOnly) {
  Table t = foreign(walked_table(), true);
  std::vector<double> weight = t.weight();
  for (double& w : weight) w *= 0.37;  // weighted counts
  t.escaped_weight *= 0.37;
  split_halves(weight, 3, t);
  ASSERT_EQ(t.halves, Halves::kEven);
  EXPECT_NE(settings_error(t, parse_model_spec("auto")), "");
  EXPECT_NE(settings_error(t, parse_model_spec("sh:auto")), "");
  EXPECT_THROW(fit_table(t, fixed("vmf:auto")), std::invalid_argument);
  for (const char* spec : {"vmf:3", "sh:4"}) {
    EXPECT_EQ(settings_error(t, parse_model_spec(spec)), "");
    FitReport report;
    const StfModel m = fit_table(t, fixed(spec), &report);
    EXPECT_EQ(model_error(m), "") << spec;
    EXPECT_EQ(report.heldout_halves, "none");
  }
}

}  // namespace
}  // namespace stf::fit
