// Gauss-Legendre rules for the sampler's one-dimensional integrals.
#pragma once

namespace stf {

// The 8-point rule on [-1, 1] (exact for polynomials up to degree 15): nodes +-x[i], weight w[i].
inline constexpr double kGauss8Node[4] = {0.1834346424956498, 0.5255324099163290, 0.7966664774136267,
                                          0.9602898564975363};
inline constexpr double kGauss8Weight[4] = {0.3626837833783620, 0.3137066458778873, 0.2223810344533745,
                                            0.1012285362903763};

// Integral of f over [a, b] by the 8-point rule.
template <typename F>
double gauss8(F f, double a, double b) {
  const double mid = 0.5 * (a + b), half = 0.5 * (b - a);
  double sum = 0;
  for (int i = 0; i < 4; ++i)
    sum += kGauss8Weight[i] * (f(mid - half * kGauss8Node[i]) + f(mid + half * kGauss8Node[i]));
  return sum * half;
}

}  // namespace stf
