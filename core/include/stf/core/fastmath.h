// Branch-free float log and sincos that the compiler vectorises inside the walk kernel.
// Both are accurate to a few ulp on the ranges the walk uses (tested in fastmath_test).
#pragma once

#include <bit>
#include <cstdint>

namespace stf {

// ln(x) for x in (0, 1] (normal floats). x = m 2^e with m in [sqrt(1/2), sqrt(2)), then
// ln(1 + f), f = m - 1, by the Cephes minimax polynomial.
inline float fast_log(float x) {
  std::int32_t bits = std::bit_cast<std::int32_t>(x);
  std::int32_t e = ((bits >> 23) & 0xff) - 127;
  float m = std::bit_cast<float>((bits & 0x007fffff) | 0x3f800000);  // [1, 2)
  bool big = m > 1.41421356f;
  m = big ? 0.5f * m : m;
  e += big ? 1 : 0;
  float f = m - 1.0f;
  float p = 7.0376836292e-2f;
  p = p * f - 1.1514610310e-1f;
  p = p * f + 1.1676998740e-1f;
  p = p * f - 1.2420140846e-1f;
  p = p * f + 1.4249322787e-1f;
  p = p * f - 1.6668057665e-1f;
  p = p * f + 2.0000714765e-1f;
  p = p * f - 2.4999993993e-1f;
  p = p * f + 3.3333331174e-1f;
  float f2 = f * f;
  float log1pf = f + f2 * (f * p - 0.5f);
  return log1pf + float(e) * 0.693147180559945f;
}

struct SinCos {
  float sin;
  float cos;
};

// sin and cos of 2 pi u for u in [0, 1]. Reducing in u (not in radians) is exact: the
// quadrant q = round(4u) and the remainder a = (4u - q) pi / 2 in [-pi/4, pi/4].
inline SinCos sincos_2pi(float u) {
  float t = 4.0f * u;
  float q = float(int(t + 0.5f));
  float a = (t - q) * 1.57079632679489662f;
  float a2 = a * a;
  float s = a + a * a2 * (-1.6666654611e-1f + a2 * (8.3321608736e-3f + a2 * -1.9515295891e-4f));
  float c = 1.0f - 0.5f * a2 +
            a2 * a2 * (4.166664568298827e-2f + a2 * (-1.388731625493765e-3f + a2 * 2.443315711809948e-5f));
  int quadrant = int(q) & 3;
  float sign = (quadrant & 2) ? -1.0f : 1.0f;
  bool odd = quadrant & 1;
  return {sign * (odd ? c : s), sign * (odd ? -s : c)};
}

// atan2 in double to ~2e-9 rad without libm, branch-free: octant reduction to
// |r| <= tan(pi/8), then the Taylor series of atan to r^19 (its first omitted term is below
// 2e-9). For binning, where a cell edge must be found, not for precise angles.
inline double fast_atan2(double y, double x) {
  constexpr double kPi = 3.14159265358979323846;
  double ax = x < 0 ? -x : x, ay = y < 0 ? -y : y;
  bool steep = ay > ax;
  double hi = steep ? ay : ax, lo = steep ? ax : ay;
  double a = lo / (hi > 0 ? hi : 1.0);  // 0 / 0 at the origin gives angle 0
  bool wide = a > 0.41421356237309503;
  double r = wide ? (a - 1) / (a + 1) : a;
  double r2 = r * r, p = 1.0 / 19;
  for (int k = 17; k >= 1; k -= 2) p = p * -r2 + 1.0 / k;  // Horner in -r^2
  double angle = r * p + (wide ? kPi / 4 : 0);
  angle = steep ? kPi / 2 - angle : angle;
  angle = x < 0 ? kPi - angle : angle;
  return y < 0 ? -angle : angle;
}

}  // namespace stf
