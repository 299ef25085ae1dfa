// What the path loop asks of a medium, in one colour channel (the role of pbrt-v4's and
// Mitsuba's Medium): where a free flight ends in a real collision, the transmittance along a
// segment, a bound on it, and the ball a stride may take. Two kinds, behind one face:
//  - homogeneous: exact exponential flights and transmittance, exp(-sigma_t t);
//  - a density grid (stf/media/density_grid.h) placed by the object's scale and translate, its
//    coefficients per unit density: delta tracking against the grid's majorant bricks for
//    flights (each tentative collision real with probability sigma_t(x) / majorant), residual
//    ratio tracking for transmittance; both unbiased (docs/render.md, "Media that vary").
// The albedo and the phase function are the same everywhere in a medium. A stride in a grid is
// exact only where the density is constant: the ball shrinks until the density over it stays
// within max <= (1 + tolerance) min (docs/render.md, "Strides through media that vary").
#pragma once

#include <array>
#include <cmath>
#include <memory>

#include "stf/hg.h"
#include "stf/media/density_grid.h"
#include "stf/media/stride_rooms.h"
#include "stf/render/path_counters.h"
#include "stf/render/pixel_rng.h"
#include "stf/vec3.h"

namespace stf::render {

// A ball a stride may take: its radius (0: none) and the sigma_t of the homogeneous medium whose
// shell transport stands for it; by_medium when the medium, not the free radius, limited it (then
// a closer look at the geometry cannot give a larger one).
struct StrideBall {
  double radius = 0, sigma_t = 0;
  bool by_medium = false;
};

// A density grid placed in an object, x_grid = (x - translate) / scale, and how far its density
// may vary over a stride's ball (below 0: no strides).
struct PlacedGrid {
  std::shared_ptr<const media::DensityGrid> grid;
  double scale = 1;
  Vec3 translate;
  double tolerance = -1;
  // The grid's stride rooms at that tolerance, where already built (media of one grid share
  // them); built by the medium where null.
  std::shared_ptr<const media::StrideRooms> rooms;
};

class ChannelMedium {
 public:
  ChannelMedium() = default;
  // Homogeneous: sigma_s and sigma_a per scene unit.
  ChannelMedium(double sigma_s, double sigma_a, double g);
  // A density grid: sigma_s and sigma_a per unit density and scene unit.
  ChannelMedium(double sigma_s, double sigma_a, double g, PlacedGrid placed);

  bool homogeneous() const { return !grid_; }
  // sigma_t where the medium is homogeneous; its largest anywhere (the majorant) where it is not.
  double sigma_t() const { return sigma_t_max_; }
  double albedo() const { return albedo_; }
  double g() const { return g_; }
  const HgParams<double>& hg() const { return hg_; }

  // The distance along w (unit) from x to the flight's real collision: HUGE_VAL where the medium
  // ends first (the caller checks the boundary before it). Null collisions are counted.
  double flight(const Vec3& x, const Vec3& w, PixelRng& rng, PathCounters& counters) const {
    if (!grid_) return homogeneous_flight(rng);
    return grid_flight(x, w, rng, counters);
  }
  // A homogeneous medium's flight: exponential at sigma_t.
  double homogeneous_flight(PixelRng& rng) const { return -std::log(rng.uniform_open0()) * inv_sigma_t_; }
  // The transmittance from x to x + length w (an unbiased estimate where the medium varies).
  double transmittance(const Vec3& x, const Vec3& w, double length, PixelRng& rng) const {
    if (!grid_) return std::exp(-sigma_t_max_ * length);
    return grid_transmittance(x, w, length, rng);
  }
  // The largest ball about x, within `free_radius` of it, that a sphere of the ladder from
  // `smallest_tau` to `largest_tau` may stand for: homogeneous, the free radius at sigma_t; a grid,
  // the free radius (or the largest sphere's at the density at x) cut to the cube of blocks
  // about x's whose densities stay within the tolerance (media::StrideRooms), at the density at
  // x (the ball's mean where the field is linear across it).
  StrideBall stride_ball(const Vec3& x, double free_radius, double smallest_tau, double largest_tau) const {
    if (!grid_) return {free_radius, sigma_t_max_};
    return grid_stride_ball(x, free_radius, smallest_tau, largest_tau);
  }
  // A lower bound of the optical depth of every segment from x of `length` inside the medium (a
  // free radius: no boundary nearer), so exp(-that) bounds what it transmits. A grid takes the
  // least density of x's majorant brick over the part of the segment the brick must hold (the
  // distance to its nearest face).
  double least_optical_depth(const Vec3& x, double length) const {
    if (!grid_) return sigma_t_max_ * length;
    return grid_least_optical_depth(x, length);
  }

 private:
  double grid_flight(const Vec3& x, const Vec3& w, PixelRng& rng, PathCounters& counters) const;
  double grid_transmittance(const Vec3& x, const Vec3& w, double length, PixelRng& rng) const;
  StrideBall grid_stride_ball(const Vec3& x, double free_radius, double smallest_tau, double largest_tau) const;
  double grid_least_optical_depth(const Vec3& x, double length) const;
  // x in the grid's lattice and its block of `edge` cells along each axis; false outside the
  // `counts` blocks (or not a number).
  bool lattice_block(const Vec3& x, int edge, const std::array<int, 3>& counts, Vec3& u, int b[3]) const;
  // How far, in scene units, every segment from lattice point u stays within the blocks of `edge`
  // cells b - k .. b + k along each axis.
  double room_within(const Vec3& u, const int b[3], int k, int edge) const;

  double sigma_t_max_ = 0, inv_sigma_t_ = 0, albedo_ = 0, g_ = 0;
  HgParams<double> hg_{};
  std::shared_ptr<const media::DensityGrid> grid_;
  double sigma_t_unit_ = 0, scale_ = 1;  // the grid's sigma_t per unit density; its placement
  double tolerance_ = -1;
  Vec3 translate_;
  std::shared_ptr<const media::StrideRooms> rooms_;
};

}  // namespace stf::render
