// von Mises-Fisher lobes on the unit sphere: density and mixtures.
#pragma once

#include <cmath>
#include <vector>

#include "stf/vec3.h"

namespace stf {

struct VmfLobe {
  double weight = 1;  // mixture weight; the weights of a mixture sum to 1
  double kappa = 0;   // concentration >= 0 (0: uniform)
  Vec3 mean{0, 0, 1};
};

// vMF density per steradian at cos(angle to the mean) = c, in the stable form
//   kappa / (2 pi (1 - exp(-2 kappa))) * exp(kappa (c - 1)),
// which neither overflows at kappa ~ 1e7 (unlike sinh) nor loses precision as kappa -> 0
// (expm1 keeps kappa / (1 - e^{-2 kappa}) -> 1/2, the uniform 1 / (4 pi)). Templated so the
// fitter can differentiate it (T = ceres::Jet).
template <typename T>
inline T vmf_pdf(const T& kappa, const T& c) {
  using std::exp;
  using std::expm1;
  T norm = kappa < T(1e-12) ? T(0.5) + T(0.5) * kappa : kappa / -expm1(T(-2) * kappa);
  return norm / T(2 * kPi) * exp(kappa * (c - T(1)));
}

inline double mixture_pdf(const std::vector<VmfLobe>& lobes, const Vec3& w) {
  double p = 0;
  for (const VmfLobe& l : lobes) p += l.weight * vmf_pdf(l.kappa, dot(l.mean, w));
  return p;
}

}  // namespace stf
