// The stiff and extreme sweep (stf/scene/stress.h): every number finite, every limit physical.
// Diffusive cases (tau = 1000 would need ~5e5 collisions per path) run under a collision cap
// whose truncated weight is booked. The table printed is for reading, not asserted on.
#include "stf/scene/stress.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

namespace stf::scene {
namespace {

constexpr long kPaths = 400;
constexpr long kCap = 20000;

TEST(StressSweep, FiniteEverywhereAndPhysicalLimits) {
  std::printf("%s\n", stress_table_header().c_str());
  std::vector<StressResult> results;
  for (const StressCase& c : stress_cases()) {
    results.push_back(run_stress_case(c, kPaths, kCap, 2));
    const StressResult& r = results.back();
    std::printf("%s\n", stress_table_row(r).c_str());
    EXPECT_TRUE(r.finite) << stress_table_row(r);
    const double n = double(kPaths), p0 = std::exp(-c.tau);
    if (c.albedo == 0) {  // only the unscattered escape: a binomial with p = exp(-tau)
      EXPECT_NEAR(r.escape, p0, 6 * std::sqrt(p0 * (1 - p0) / n) + 1.0 / n) << stress_table_row(r);
    }
    if (c.tau <= 1e-6) {  // every path leaves unscattered
      EXPECT_EQ(r.escape, 1.0) << stress_table_row(r);
    }
  }
  // For fixed (g, tau), escape falls with falling albedo (same random numbers: monotone up to noise).
  for (std::size_t i = 1; i < results.size(); ++i) {
    const StressResult &a = results[i - 1], &b = results[i];
    if (a.c.g != b.c.g || a.c.tau != b.c.tau) continue;
    EXPECT_GE(b.escape + 4 * std::sqrt(0.25 / kPaths), a.escape) << stress_table_row(a) << "\n" << stress_table_row(b);
  }
}

}  // namespace
}  // namespace stf::scene
