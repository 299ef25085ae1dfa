// The density of exit points inside one alpha bin: proportional to exp(tilt u), with u in
// [0, 1] the fraction of the bin's area (uniform in cos(alpha)) from its lower alpha edge.
// Tilt 0 is uniform in area. Forward-scattering media need it: their escapes after two or
// more collisions crowd towards alpha = 0 by a factor of 2-3 across the first bins.
#pragma once

#include <cmath>

namespace stf {

// Below this |tilt| the density is 1 to within 1e-8 and the uniform forms are used.
inline constexpr double kFlatTilt = 1e-8;
// Fits are clamped to |tilt| <= kMaxTilt (a factor e^40 across a bin: all in one edge).
inline constexpr double kMaxTilt = 40;

// Density in u of the tilted law.
inline double tilt_density(double tilt, double u) {
  return std::abs(tilt) < kFlatTilt ? 1.0 : tilt * std::exp(tilt * u) / std::expm1(tilt);
}

// Its probability of [u0, u1].
inline double tilt_mass(double tilt, double u0, double u1) {
  if (std::abs(tilt) < kFlatTilt) return u1 - u0;
  return (std::expm1(tilt * u1) - std::expm1(tilt * u0)) / std::expm1(tilt);
}

// The u whose probability below is xi (exact inverse of the distribution function), with
// expm1(tilt) given (a sampler caches it per bin).
inline double tilt_quantile(double tilt, double expm1_tilt, double xi) {
  if (std::abs(tilt) < kFlatTilt) return xi;
  const double u = std::log1p(xi * expm1_tilt) / tilt;
  return u < 0 ? 0.0 : u > 1 ? 1.0 : u;
}
inline double tilt_quantile(double tilt, double xi) { return tilt_quantile(tilt, std::expm1(tilt), xi); }

}  // namespace stf
