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

}  // namespace stf
