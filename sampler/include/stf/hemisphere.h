// The outward hemisphere of an alpha bin: exit directions satisfy w . n >= 0 at the exit point's
// normal n(alpha) = (sin alpha, 0, cos alpha) (in the frame where the exit point lies in the
// x-z plane), and the density per steradian falls to zero at grazing like w . n. Hemispherical
// vMF models multiply each lobe by the bin's mean outward cosine (mean_exit_cosine) and
// renormalise it, so they respect both (docs/design.md, "Fitting").
#pragma once

#include <algorithm>
#include <cmath>

#include "stf/vec3.h"

namespace stf {

// An antiderivative of max(0, cos u): sin u + 1 on [-pi/2, pi/2], 2 on [pi/2, 3pi/2], growing
// by 2 every period.
inline double positive_cos_antiderivative(double u) {
  const double period = std::floor((u + 0.5 * kPi) / (2 * kPi));
  const double r = u - 2 * kPi * period;  // in [-pi/2, 3pi/2)
  return 2 * period + (r <= 0.5 * kPi ? std::sin(r) + 1 : 2.0);
}

// The mean over alpha in [a0, a1] (uniform in alpha) of max(0, w . n(alpha)): with
// w . n = rho cos(alpha - phi), rho = |(w_x, w_z)|, phi = atan2(w_x, w_z), in closed form.
inline double mean_exit_cosine(const Vec3& w, double a0, double a1) {
  const double rho = std::hypot(w.x, w.z), phi = std::atan2(w.x, w.z);
  return rho * (positive_cos_antiderivative(a1 - phi) - positive_cos_antiderivative(a0 - phi)) / (a1 - a0);
}

// mean_exit_cosine of one bin (at most pi wide) with its edge normals precomputed. Where w is
// on the outward side at both edges (most directions) w . n(alpha) >= 0 all through the bin, and
// the mean is linear in w: no trigonometry per direction. On the inward side at both edges it is
// 0 (the outward arc of alpha is pi long and cannot fit between them).
class OutwardBin {
 public:
  OutwardBin() = default;
  OutwardBin(double a0, double a1)
      : a0_(a0), a1_(a1), s0_(std::sin(a0)), c0_(std::cos(a0)), s1_(std::sin(a1)), c1_(std::cos(a1)),
        inv_width_(1 / (a1 - a0)) {}
  double operator()(const Vec3& w) const {
    const double d0 = w.x * s0_ + w.z * c0_, d1 = w.x * s1_ + w.z * c1_;  // w . n at the edges
    if (d0 >= 0 && d1 >= 0) return (w.x * (c0_ - c1_) + w.z * (s1_ - s0_)) * inv_width_;
    if (d0 <= 0 && d1 <= 0) return 0.0;
    return mean_exit_cosine(w, a0_, a1_);
  }

 private:
  double a0_ = 0, a1_ = kPi, s0_ = 0, c0_ = 1, s1_ = 0, c1_ = -1, inv_width_ = 1 / kPi;
};

}  // namespace stf
