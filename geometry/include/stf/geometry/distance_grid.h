// A precomputed lower bound of the distance to a scene's boundary: values v(c) <= d(c) at the
// centres of a regular grid over a region, and at any point x of cell c the bound v(c) - |x - c|,
// which never exceeds d(x) (the distance is 1-Lipschitz). One load and a square root per query,
// against a BVH search for the exact distance.
//
// v is exact within a band of three cells of the surface (every triangle's neighbourhood
// rasterised, point-triangle distances in double), where the smallest spheres need it; deeper
// it is the band's width or the best bound from the exact distances at the eight centres of cells
// 4 times as large around c (a centre's distance less its distance to c), whichever is larger.
// Building costs one Embree query per coarse cell instead of one per cell.
//
// Values are 16-bit multiples of a unit (the largest value / 65535, rounded down) in bricks of
// 4 x 4 x 4 cells, one z-slice of a brick per 32 bytes: a query's cell and its neighbours share a
// few cache lines and pages, where rows of floats put the eight of a tight query on four lines of
// two pages (queries stall on the load; bench/distance_cost).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "stf/core/parallel.h"
#include "stf/geometry/boundary.h"

namespace stf::geometry {

class DistanceGrid {
 public:
  // A grid over `region` with `cells` cells along its largest side (cubic cells), the distances
  // from `boundary`. Throws std::invalid_argument for cells outside [4, 2048].
  DistanceGrid(const Boundary& boundary, const Bounds& region, int cells, const RunContext& run = {});

  // A lower bound of the distance from x to the boundary (0 outside the region).
  double lower_bound(const Vec3& x) const {
    const double fx = (x.x - origin_.x) * inv_cell_, fy = (x.y - origin_.y) * inv_cell_, fz = (x.z - origin_.z) * inv_cell_;
    if (!(fx >= 0 && fy >= 0 && fz >= 0 && fx < n_[0] && fy < n_[1] && fz < n_[2])) return 0;
    const int i = int(fx), j = int(fy), k = int(fz);
    return std::max(0.0, value(i, j, k) - length(x - centre(i, j, k)) - slack_);
  }

  // The largest of the bounds of the eight cells whose centres surround x: near a surface one of
  // them lies deeper along its normal than x, and its bound is nearly the distance itself. Eight
  // loads and square roots, for where the one-cell bound is too small for a sphere.
  double tight_lower_bound(const Vec3& x) const {
    const double fx = (x.x - origin_.x) * inv_cell_ - 0.5, fy = (x.y - origin_.y) * inv_cell_ - 0.5,
                 fz = (x.z - origin_.z) * inv_cell_ - 0.5;
    if (!(fx >= 0 && fy >= 0 && fz >= 0 && fx < n_[0] - 1 && fy < n_[1] - 1 && fz < n_[2] - 1)) return lower_bound(x);
    const int i = int(fx), j = int(fy), k = int(fz);
    // Offsets along each axis to the lower and upper centres, squared, summed in the eight ways
    // and rooted together (the compiler packs the roots into vector instructions).
    const double ox = x.x - (origin_.x + (i + 0.5) * cell_), oy = x.y - (origin_.y + (j + 0.5) * cell_),
                 oz = x.z - (origin_.z + (k + 0.5) * cell_);
    const double sx[2] = {ox * ox, (ox - cell_) * (ox - cell_)}, sy[2] = {oy * oy, (oy - cell_) * (oy - cell_)},
                 sz[2] = {oz * oz, (oz - cell_) * (oz - cell_)};
    double apart[8], v[8];
    for (int c = 0; c < 8; ++c) apart[c] = sx[c & 1] + sy[(c >> 1) & 1] + sz[c >> 2];
    for (double& a : apart) a = std::sqrt(a);
    for (int c = 0; c < 8; ++c) v[c] = value(i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2));
    double best = 0;
    for (int c = 0; c < 8; ++c) best = std::max(best, v[c] - apart[c]);
    return std::max(0.0, best - slack_);
  }

  std::size_t bytes() const { return value_.size() * sizeof(std::uint16_t); }
  double cell() const { return cell_; }
  double band() const { return 3 * cell_; }
  // The radius of the largest ball inside mesh k of the boundary, to within a coarse cell's
  // half-diagonal: the largest exact distance at a coarse centre inside it.
  double deepest(const Boundary& boundary, int mesh) const;

 private:
  std::size_t index(int i, int j, int k) const {
    const std::size_t brick = (std::size_t(k >> 2) * std::size_t(nc_[1]) + std::size_t(j >> 2)) * std::size_t(nc_[0]) +
                              std::size_t(i >> 2);
    return brick * 64 + std::size_t((i & 3) | (j & 3) << 2 | (k & 3) << 4);
  }
  double value(int i, int j, int k) const { return value_[index(i, j, k)] * unit_; }
  void quantise(const std::vector<double>& v, const RunContext& run);
  Vec3 centre(int i, int j, int k) const { return origin_ + cell_ * Vec3{i + 0.5, j + 0.5, k + 0.5}; }
  std::vector<double> coarse(const Boundary& boundary, const RunContext& run) const;
  // The best bound at cell (i, j, k)'s centre from the coarse grid's exact distances.
  double deep_bound(int i, int j, int k) const;
  void rasterise_band(const Boundary& boundary, std::vector<double>& near, const RunContext& run) const;

  Vec3 origin_;
  double cell_ = 0, inv_cell_ = 0, slack_ = 0;
  int n_[3] = {0, 0, 0};
  double unit_ = 0;
  std::vector<std::uint16_t> value_;  // v at cell centres in units, rounded down, in bricks
  int nc_[3] = {0, 0, 0};  // coarse cells along each axis, each a brick of 4 x 4 x 4 cells
  std::vector<double> coarse_;  // exact distances at the coarse cells' centres
};

}  // namespace stf::geometry
