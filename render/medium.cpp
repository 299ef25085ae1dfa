#include "stf/render/medium.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "stf/media/tracking.h"

namespace stf::render {

ChannelMedium::ChannelMedium(double sigma_s, double sigma_a, double g)
    : sigma_t_max_(sigma_s + sigma_a), inv_sigma_t_(1 / sigma_t_max_),
      albedo_(sigma_s / sigma_t_max_), g_(g), hg_(HgParams<double>::make(g)) {}

ChannelMedium::ChannelMedium(double sigma_s, double sigma_a, double g, PlacedGrid placed)
    : ChannelMedium(sigma_s, sigma_a, g) {
  sigma_t_unit_ = sigma_s + sigma_a, scale_ = placed.scale, translate_ = placed.translate, tolerance_ = placed.tolerance;
  sigma_t_max_ = sigma_t_unit_ * placed.grid->max_density();
  inv_sigma_t_ = 1 / sigma_t_max_;
  grid_ = std::move(placed.grid);
  rooms_ = placed.rooms;
  if (tolerance_ >= 0 && !rooms_) rooms_ = std::make_shared<const media::StrideRooms>(stride_rooms(*grid_, tolerance_));
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

bool ChannelMedium::lattice_block(const Vec3& x, int edge, const std::array<int, 3>& counts, Vec3& u, int b[3]) const {
  u = grid_->to_lattice((x - translate_) / scale_);
  const double l[3] = {u.x, u.y, u.z};
  for (std::size_t a = 0; a < 3; ++a) {
    b[a] = int(std::floor((l[a] + 1) / edge));
    if (!(b[a] >= 0 && b[a] < counts[a])) return false;  // NaN too
  }
  return true;
}

// A ball's extent along lattice axis a is its radius times the axis's reach.
double ChannelMedium::room_within(const Vec3& u, const int b[3], int k, int edge) const {
  const double l[3] = {u.x, u.y, u.z};
  double room = HUGE_VAL;
  for (int a = 0; a < 3; ++a) {
    const double lower = media::DensityGrid::block_lower(b[a] - k, edge), upper = media::DensityGrid::block_lower(b[a] + k + 1, edge);
    room = std::min(room, std::min(l[a] - lower, upper - l[a]) / grid_->lattice_reach(a));
  }
  return room * scale_;
}

double ChannelMedium::grid_least_optical_depth(const Vec3& x, double length) const {
  Vec3 u;
  int b[3];
  if (!lattice_block(x, media::DensityGrid::kBrick, grid_->brick_counts(), u, b)) return 0;
  // The brick's least corner value bounds the trilinear field in it from below.
  const double inside = room_within(u, b, 0, media::DensityGrid::kBrick);
  return sigma_t_unit_ * grid_->brick(b[0], b[1], b[2]).min * std::min(length, inside);
}

StrideBall ChannelMedium::grid_stride_ball(const Vec3& x, double free_radius, double smallest_tau,
                                           double largest_tau) const {
  Vec3 u;
  int b[3];
  if (tolerance_ < 0 || !lattice_block(x, media::StrideRooms::kBlock, rooms_->counts, u, b)) return {0, 0, true};
  // The cube of blocks within k of x's keeps the tolerance (k < 0: not even x's block, as where
  // the density varies most): the ball may reach its nearest face along every lattice axis.
  const int k = rooms_->at(b[0], b[1], b[2]);
  if (k < 0) return {0, 0, true};
  const double room = room_within(u, b, k, media::StrideRooms::kBlock);
  const double sigma_t = sigma_t_unit_ * grid_->lattice_density(u);
  // No sphere of the ladder is larger than largest_tau at the ball's least density.
  const double r = std::min({free_radius, room, largest_tau * (1 + tolerance_) / sigma_t});
  if (!(sigma_t * r >= smallest_tau)) return {0, 0, r < free_radius};
  return {r, sigma_t, r < free_radius};
}

}  // namespace stf::render
