// Henyey-Greenstein phase function: sample / pdf pair over mu = cos(theta).
#pragma once

#include <cmath>

namespace stf {

template <typename T>
struct CosSin {
  T cos_theta;
  T sin_theta;
};

// Inverts the HG CDF in a form without cancellation for every g in (-1, 1). The textbook
// inversion (1 + g^2 - s^2) / (2g) divides by g and cancels for small |g| and near |g| -> 1;
// here 1 + mu and 1 - mu are each written as a product of positive factors,
//   1 + mu = 2 xi (1+g)^2 (1 - g + g xi) / D^2,   1 - mu = 2 (1-xi) (1-g)^2 (1 + g xi) / D^2,
// with D = 1 - g + 2 g xi, so mu and sin(theta) = sqrt((1+mu)(1-mu)) keep full relative
// precision at g = 0 (exactly isotropic, no branch needed), at |g| -> 1, and at xi in {0, 1}.
//
// 1 - g and 1 + g are taken in double before any narrowing to float, so g = 0.9999 keeps
// its distance from 1.
template <typename T>
struct HgParams {
  T g, one_minus_g, one_plus_g;
  static HgParams make(double g) { return {T(g), T(1 - g), T(1 + g)}; }
};

template <typename T>
inline CosSin<T> sample_hg(const HgParams<T>& h, T xi) {
  T d = h.one_minus_g + T(2) * h.g * xi;
  T inv_d2 = T(1) / (d * d);
  T one_plus = T(2) * xi * h.one_plus_g * h.one_plus_g * (h.one_minus_g + h.g * xi) * inv_d2;
  T one_minus = T(2) * (T(1) - xi) * h.one_minus_g * h.one_minus_g * (T(1) + h.g * xi) * inv_d2;
  T mu = one_plus < one_minus ? one_plus - T(1) : T(1) - one_minus;
  return {mu, std::sqrt(one_plus * one_minus)};
}

// Density of mu = cos(theta) on [-1, 1] (azimuth integrated out); 0 outside.
inline double hg_pdf_mu(double g, double mu) {
  if (mu < -1 || mu > 1) return 0;
  double denom = 1 + g * g - 2 * g * mu;
  return 0.5 * (1 - g * g) / (denom * std::sqrt(denom));
}

}  // namespace stf
