// Random numbers and quadrature shared by the sampler tests.
#pragma once

#include <cstdint>

#include "stf/core/rng.h"
#include "stf/quadrature.h"

namespace stf::test {

// Uniforms in [0, 1) from SplitMix64.
struct Uniforms {
  std::uint64_t state;
  double operator()() { return double(splitmix64(state) >> 11) * 0x1p-53; }
};

// Composite 8-point Gauss-Legendre of f over [a, b] in `panels` panels.
template <typename F>
double integrate(F f, double a, double b, int panels = 64) {
  const double h = (b - a) / panels;
  double s = 0;
  for (int p = 0; p < panels; ++p) s += gauss8(f, a + p * h, a + (p + 1) * h);
  return s;
}

}  // namespace stf::test
