#include "stf/render/medium.h"

#include <cmath>

#include "stf/media/tracking.h"

namespace stf::render {

ChannelMedium::ChannelMedium(double sigma_s, double sigma_a, double g)
    : sigma_t_max_(sigma_s + sigma_a), sigma_t_min_(sigma_t_max_), inv_sigma_t_(1 / sigma_t_max_),
      albedo_(sigma_s / sigma_t_max_), g_(g), hg_(HgParams<double>::make(g)) {}

ChannelMedium::ChannelMedium(double sigma_s, double sigma_a, double g, PlacedGrid placed)
    : ChannelMedium(sigma_s, sigma_a, g) {
  sigma_t_unit_ = sigma_s + sigma_a, scale_ = placed.scale, translate_ = placed.translate, tolerance_ = placed.tolerance;
  sigma_t_max_ = sigma_t_unit_ * placed.grid->max_density(), sigma_t_min_ = 0;  // outside the support the density is 0
  inv_sigma_t_ = 1 / sigma_t_max_;
  grid_ = std::move(placed.grid);
}

// The grid's frame is the scene's scaled by 1 / scale: a distance t there is t * scale here, and
// sigma_t per grid unit is scale times sigma_t per scene unit.
double ChannelMedium::grid_flight(const Vec3& x, const Vec3& w, PixelRng& rng, PathCounters& counters) const {
  const media::Flight f = media::delta_track(*grid_, sigma_t_unit_ * scale_, (x - translate_) / scale_, w, HUGE_VAL,
                                             [&rng] { return rng.uniform(); });
  counters.null_collisions += f.null_collisions;
  return f.collided ? f.t * scale_ : HUGE_VAL;
}

double ChannelMedium::grid_transmittance(const Vec3& x, const Vec3& w, double length, PixelRng& rng) const {
  const media::Transmittance t = media::ratio_track(*grid_, sigma_t_unit_ * scale_, (x - translate_) / scale_, w,
                                                    length / scale_, [&rng] { return rng.uniform(); });
  return t.transmittance;
}

StrideBall ChannelMedium::grid_stride_ball(const Vec3& x, double free_radius, double smallest_tau,
                                           double largest_tau) const {
  if (tolerance_ < 0) return {0, 0, true};
  const Vec3 u = (x - translate_) / scale_;
  // Every ball holds x's brick: where it varies too much, none may be taken (asked first: most
  // collisions in a varying grid end here).
  if (!within_tolerance(grid_->range_over_ball(u, 0))) return {0, 0, true};
  const double sigma_t = sigma_t_unit_ * grid_->density(u);
  // No sphere of the ladder is larger than largest_tau at the ball's least density.
  double r = std::min(free_radius, largest_tau * (1 + tolerance_) / sigma_t);
  bool shrunk = r < free_radius;
  for (; sigma_t * r >= smallest_tau; r *= 0.5, shrunk = true)
    if (within_tolerance(grid_->range_over_ball(u, r / scale_))) return {r, sigma_t, shrunk};
  return {0, 0, shrunk};
}

}  // namespace stf::render
