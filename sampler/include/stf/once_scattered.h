// The once-scattered part of the exit distribution (docs/design.md, "Singular parts").
//
// A path starts at the centre of the unit sphere heading +z, collides at depth s (density
// tau e^{-tau s}), survives with the albedo, turns by Henyey-Greenstein to mu = cos(theta) with a
// uniform azimuth phi, and leaves after t(s, mu) = -s mu + sqrt(1 - s^2 (1 - mu^2)) with
// probability e^{-tau t}. With u the HG quantile of mu (mu = mu(u) is HG-distributed for u
// uniform), the escapes have the density over (s, u) in [0, 1)^2
//   q(s, u) = albedo tau exp(-tau L(s, mu(u))),   L = s + t >= 1 the path's length.
// Rotated so that the exit point lies in the x-z plane, the exit direction is (sin theta, 0, mu):
// given the exit point, directions lie on one great circle, a set that no density on the
// sphere of directions holds. So this part is drawn exactly, never fitted.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "stf/alias.h"
#include "stf/hg.h"
#include "stf/vec3.h"

namespace stf {

// Distance from (0, 0, s) along a direction with z component mu to the unit sphere, without the
// cancellation of the textbook form where the path leaves almost straight from near the surface.
inline double exit_distance_from_axis(double s, double mu) {
  const double root = std::sqrt(std::max(0.0, 1 - s * s * (1 - mu) * (1 + mu)));
  return mu > 0 ? (1 - s) * (1 + s) / (s * mu + root) : root - s * mu;
}

// cos of the exit angle alpha (the exit point's angle from +z) of that path.
inline double exit_cos_alpha(double s, double mu) { return s + exit_distance_from_axis(s, mu) * mu; }

// Probability, divided by the albedo, that a path escapes after exactly one collision.
double once_scattered_probability(double tau, double g);

class OnceScattered {
 public:
  OnceScattered() = default;
  OnceScattered(double tau, double g);

  // An exact draw of (exit point, exit direction) in the local frame (start direction +z, the
  // azimuth applied): rejection from a bound that is constant on each cell of an (s, u) grid.
  // u0 picks the cell (its remainder places s), u1 the azimuth, u2 places u and u3 accepts; a
  // rejected try continues with a stream seeded from the four numbers.
  void sample(double u0, double u1, double u2, double u3, Vec3& point, Vec3& direction) const;
  // The share of tries that are accepted (by quadrature).
  double acceptance() const;

  // The (s, u) grid: s edges crowd towards the centre, where paths scattered backwards in a
  // thick sphere collide, and towards the surface; u edges are uniform (HG's own measure).
  static std::vector<double> s_edges();
  static std::vector<double> u_edges();
  // HG's quantile function: mu(u).
  double mu(double u) const { return sample_hg(hg_, u).cos_theta; }

 private:
  double path_length(double s, double mu) const { return s + exit_distance_from_axis(s, mu); }
  // One try from cell numbers (v0 for the cell, v1 places s, v2 places u, v3 accepts); false if
  // rejected.
  bool try_draw(double v0, double v2, double v3, double& s, double& mu, double& sin_theta) const;

  double tau_ = 0;
  HgParams<double> hg_ = HgParams<double>::make(0);
  std::vector<double> s_edges_, u_edges_;
  std::vector<double> min_length_;  // per cell, the least L: the bound is tau e^{-tau L_min}
  AliasTable cells_;
  double bound_mass_ = 0;
};

}  // namespace stf
