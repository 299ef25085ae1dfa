#include "stf/core/fastmath.h"

#include <gtest/gtest.h>

#include <cmath>

namespace stf {
namespace {

// Error relative to what float can resolve: 4 ulp of the result, or of x where log x ~ 0.
double log_error_in_tolerances(float x) {
  double exact = std::log(double(x));
  double tol = std::max(4 * std::abs(exact), 1.0) * 0x1p-24;
  return std::abs(double(fast_log(x)) - exact) / tol;
}

TEST(FastMath, LogMatchesStdOnUnitInterval) {
  // Every 7th 24-bit uniform the walk can draw, (k + 1) / 2^24, and tiny normals.
  double worst = 0;
  for (std::uint32_t k = 0; k < (1u << 24); k += 7) worst = std::max(worst, log_error_in_tolerances(float(k + 1) * 0x1p-24f));
  for (float x : {1e-30f, 1e-10f, 0.5f, 0.7071f, 0.70711f, 1.0f}) worst = std::max(worst, log_error_in_tolerances(x));
  EXPECT_LE(worst, 1.0);
  EXPECT_EQ(fast_log(1.0f), 0.0f);
}

TEST(FastMath, SinCosOfTwoPiU) {
  double worst = 0;
  for (int k = 0; k <= (1 << 20); ++k) {
    float u = float(k) / float(1 << 20);
    SinCos sc = sincos_2pi(u);
    double angle = 2 * 3.14159265358979323846 * double(u);
    worst = std::max({worst, std::abs(sc.sin - std::sin(angle)), std::abs(sc.cos - std::cos(angle))});
  }
  EXPECT_LT(worst, 3e-7);
}

TEST(FastMath, Atan2WithinTwoNanoRadiansEverywhere) {
  double worst = 0;
  for (int k = 0; k <= 200000; ++k) {
    double angle = -3.14159265358979323846 + 2 * 3.14159265358979323846 * k / 200000;
    for (double r : {1e-300, 1e-8, 1.0, 1e8}) {
      double y = r * std::sin(angle), x = r * std::cos(angle);
      worst = std::max(worst, std::abs(fast_atan2(y, x) - std::atan2(y, x)));
    }
  }
  EXPECT_LT(worst, 2e-9);
  EXPECT_EQ(fast_atan2(0.0, 0.0), 0.0);
  EXPECT_NEAR(fast_atan2(0.0, -1.0), 3.14159265358979323846, 1e-15);
  EXPECT_NEAR(fast_atan2(-1.0, 0.0), -1.5707963267948966, 1e-15);
}

}  // namespace
}  // namespace stf
