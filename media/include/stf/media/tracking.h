// Free flights and transmittance through a DensityGrid (extinction sigma_per_density * density),
// against its majorant bricks: a 3D DDA walks the bricks a ray crosses, in lattice coordinates
// (the map is affine, so the ray's parameter t is the same distance there), from where the ray
// enters the support to where it leaves it or reaches t_max, and skips bricks whose max is 0.
//
// Templates over the ray (o, unit w, in the grid's frame) and a callable `uniform()` returning a
// double in [0, 1) or (0, 1). Both estimators are unbiased: restarting the exponential at a brick
// face is exact (it has no memory), and within a brick the majorant bounds the field exactly.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "stf/media/density_grid.h"

namespace stf::media {

struct Flight {
  double t = 0;        // the collision's distance, or t_max
  bool collided = false;  // false: no real collision before t_max
  std::int64_t null_collisions = 0;
};

struct Transmittance {
  double transmittance = 1;
  std::int64_t tentative = 0;  // tentative collisions sampled
};

namespace tracking_detail {

inline double axis(const Vec3& v, int a) { return a == 0 ? v.x : a == 1 ? v.y : v.z; }

// Narrows [t0, t1] to the part of the ray u + t d inside the box; false where none is left.
inline bool clip_ray(const Box& box, const Vec3& u, const Vec3& d, double& t0, double& t1) {
  for (int a = 0; a < 3; ++a) {
    const double p = axis(u, a), v = axis(d, a), lo = axis(box.lower, a), hi = axis(box.upper, a);
    if (v == 0) {
      if (p < lo || p > hi) return false;
      continue;
    }
    const double ta = (lo - p) / v, tb = (hi - p) / v;
    t0 = std::max(t0, std::min(ta, tb)), t1 = std::min(t1, std::max(ta, tb));
  }
  return t0 < t1;
}

// Calls visit(t_begin, t_end, brick) for each brick segment of the ray u + t d within the
// support and [0, t_max], in order, until visit returns false (Amanatides and Woo's DDA over
// brick coordinates (u + 1) / kBrick). A point a rounding error past a brick face is bounded by
// the brick's neighbour: the trackers clamp the field into the brick's range.
template <class Visit>
void walk_bricks(const DensityGrid& grid, const Vec3& u, const Vec3& d, double t_max, Visit&& visit) {
  double t = 0, t_end = t_max;
  if (!std::isfinite(u.x + u.y + u.z + d.x + d.y + d.z) || !clip_ray(grid.lattice_support(), u, d, t, t_end)) return;
  constexpr double B = DensityGrid::kBrick;
  const auto& counts = grid.brick_counts();
  int cell[3], step[3];
  double t_next[3], t_step[3];
  for (int a = 0; a < 3; ++a) {
    const double p = axis(u, a) + t * axis(d, a), v = axis(d, a);
    cell[a] = std::clamp(int(std::floor((p + 1) / B)), 0, counts[a] - 1);
    step[a] = v > 0 ? 1 : v < 0 ? -1 : 0;
    const double face = DensityGrid::brick_lower(cell[a] + (v > 0 ? 1 : 0));
    t_next[a] = v == 0 ? std::numeric_limits<double>::infinity() : t + (face - p) / v;
    t_step[a] = v == 0 ? 0 : B / std::abs(v);
  }
  while (t < t_end) {
    const int a = t_next[0] <= t_next[1] ? (t_next[0] <= t_next[2] ? 0 : 2) : (t_next[1] <= t_next[2] ? 1 : 2);
    const double t_leave = std::max(t, std::min(t_next[a], t_end));  // never back, whatever the rounding
    if (!visit(t, t_leave, grid.brick(cell[0], cell[1], cell[2]))) return;
    t = t_leave;
    cell[a] += step[a];
    if (cell[a] < 0 || cell[a] >= counts[a]) return;
    t_next[a] += t_step[a];
  }
}

}  // namespace tracking_detail

// Delta (Woodcock) tracking: tentative collisions at rate sigma * brick max, each real with
// probability density / max. collided = false: no real collision before t_max (t = t_max).
template <class Uniform>
Flight delta_track(const DensityGrid& grid, double sigma_per_density, const Vec3& o, const Vec3& w, double t_max,
                   Uniform&& uniform) {
  Flight flight{t_max, false, 0};
  if (!(sigma_per_density > 0)) return flight;
  const Vec3 u = grid.to_lattice(o), d = grid.lattice_direction(w);
  tracking_detail::walk_bricks(grid, u, d, t_max, [&](double t, double t_leave, const DensityGrid::Brick& brick) {
    if (brick.max <= 0) return true;
    const double rate = sigma_per_density * brick.max;
    while (true) {
      t -= std::log(1 - uniform()) / rate;
      if (t >= t_leave) return true;
      const double density = std::min(grid.lattice_density(u + d * t), double(brick.max));
      if (uniform() * brick.max < density) {
        flight.t = t, flight.collided = true;
        return false;
      }
      ++flight.null_collisions;
    }
  });
  return flight;
}

// Residual ratio tracking (Novak, Selle and Jarosz 2014) with the brick's min as control:
// exp(-sigma min length) per brick segment, times ratio tracking of the residual at rate
// sigma (max - min). Exact, with no sampling, where a brick is constant.
template <class Uniform>
Transmittance ratio_track(const DensityGrid& grid, double sigma_per_density, const Vec3& o, const Vec3& w,
                          double t_max, Uniform&& uniform) {
  Transmittance result;
  if (!(sigma_per_density > 0)) return result;
  const Vec3 u = grid.to_lattice(o), d = grid.lattice_direction(w);
  tracking_detail::walk_bricks(grid, u, d, t_max, [&](double t, double t_leave, const DensityGrid::Brick& brick) {
    const double control = brick.min, spread = double(brick.max) - control;
    result.transmittance *= std::exp(-sigma_per_density * control * (t_leave - t));
    if (spread <= 0) return true;
    const double rate = sigma_per_density * spread;
    while (true) {
      t -= std::log(1 - uniform()) / rate;
      if (t >= t_leave) return result.transmittance > 0;
      ++result.tentative;
      const double density = std::clamp(grid.lattice_density(u + d * t), control, double(brick.max));
      result.transmittance *= 1 - (density - control) / spread;
    }
  });
  return result;
}

}  // namespace stf::media
