// The density of a heterogeneous medium on a lattice: values at lattice points, an affine map
// between the grid's frame ("object frame": the grid's world coordinates) and the lattice, and the
// trilinear field between them, zero outside the stored region (as if padded by one layer of
// zeros, so the field falls to zero across the last cell). Read from files or given as values:
// - OpenVDB (.vdb): the float grid named `density`, else the file's only float grid; voxel values
//   at integer index coordinates, the grid's linear index-to-world map, trilinear as
//   openvdb::tools::BoxSampler; inactive voxels are 0 whatever the background.
// - NumPy (.npy, float32 or float64, little-endian, C order, shape [nx, ny, nz]) with bounds
//   [x0, x1] x [y0, y1] x [z0, z1]: value [i, j, k] at the voxel centre x0 + (i + 1/2)(x1 - x0)/nx
//   (y, z alike), and 0 outside the bounds.
//
// A majorant grid of bricks (kBrick^3 cells each) bounds the field from above and below for
// delta and ratio tracking (stf/media/tracking.h) and for strides.
//
// Values are stored as float (memory) and everything is computed in double.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "stf/media/box.h"
#include "stf/vec3.h"

namespace stf::media {

struct Lattice;  // what the readers hand over (media/lattice.h)

class DensityGrid {
 public:
  // Cells per brick edge. 8: 2 floats per 512 values (0.4 % more memory), and the best compromise
  // measured: tracking 200,000 random rays through a 160^3 cloud-like field (2-core x86-64), 8
  // stayed within 15 % of the best of 4, 8 and 16 both thin and 10x denser; 4 took 38 % longer
  // when thin (DDA steps), 16 took 67 % longer when dense (null collisions).
  static constexpr int kBrick = 8;

  // Reads a .vdb or .npy file (by extension); `bounds` is required for .npy and refused for .vdb.
  // Throws std::runtime_error whose message is one line "PATH: what is wrong".
  static DensityGrid read(const std::string& path, const std::optional<Box>& bounds);
  // Values [nx * ny * nz] in C order with .npy's convention: value [i, j, k] at the centre of
  // voxel (i, j, k) of `bounds` cut into nx x ny x nz voxels. Throws std::invalid_argument in one
  // line.
  static DensityGrid from_values(std::vector<float> values, int nx, int ny, int nz, const Box& bounds);

  // The density at x, a point of the grid's frame.
  double density(const Vec3& x) const { return lattice_density(to_lattice(x)); }
  // A box of the grid's frame outside which the density is 0: the non-zero values' trilinear
  // support, clipped to the bounds (the box around it, where the map rotates).
  Box support() const;
  // The largest and smallest density over the support.
  double max_density() const { return max_density_; }
  double min_density() const { return min_density_; }
  // Memory held: values and bricks.
  std::size_t bytes() const;

  // The lattice, where tracking walks: lattice point (i, j, k) holds value [i, j, k], at lattice
  // coordinates (i, j, k). The map is affine, so a ray's parameter is the same distance in both.
  Vec3 to_lattice(const Vec3& x) const;
  // The lattice displacement of a unit step along w (a direction of the grid's frame).
  Vec3 lattice_direction(const Vec3& w) const;
  // The trilinear field at lattice coordinates u (zero outside the clip region).
  double lattice_density(const Vec3& u) const;
  // The support in lattice coordinates (within the clip region).
  const Box& lattice_support() const { return lattice_support_; }

  // The majorant grid. Brick b along an axis covers lattice coordinates [b kBrick - 1,
  // (b + 1) kBrick - 1]: the cells from the padding's (-1) on. Its min and max are those of the
  // lattice values (padding included) at the corners of its cells, which bound the trilinear field
  // over it exactly (a trilinear value is a convex combination of its cell's corners).
  struct Brick {
    float min = 0, max = 0;
  };
  const std::array<int, 3>& brick_counts() const { return brick_counts_; }
  const Brick& brick(int bx, int by, int bz) const {
    return bricks_[(std::size_t(bx) * std::size_t(brick_counts_[1]) + std::size_t(by)) * std::size_t(brick_counts_[2]) +
                   std::size_t(bz)];
  }
  static double brick_lower(int b) { return block_lower(b, kBrick); }
  // Where block b of `edge` cells begins along a lattice axis (blocks count from the padding's
  // cell, -1, as the bricks do).
  static double block_lower(int b, int edge) { return double(b) * edge - 1.0; }
  // The lattice extent, along lattice axis a, of a unit length of the grid's frame (row a of the
  // world-to-lattice matrix): a ball of radius r spans r times this about its centre.
  double lattice_reach(int a) const { return lattice_reach_[std::size_t(a)]; }
  // The ranges of blocks of `edge`^3 cells, by the bricks' rule (block b along an axis covers
  // lattice coordinates [b edge - 1, (b + 1) edge - 1]), in brick() order for their counts.
  std::vector<Brick> block_ranges(int edge, std::array<int, 3>& counts) const;

 private:
  explicit DensityGrid(Lattice&& lattice);
  double value(std::int64_t i, std::int64_t j, std::int64_t k) const;
  void find_support();
  double min_over_support() const;
  void build_bricks();

  std::array<std::int64_t, 3> dims_{};
  std::vector<float> values_;
  std::array<std::array<double, 4>, 3> to_world_{};    // x = A u + t: columns 0-2 are A, 3 is t
  std::array<std::array<double, 4>, 3> to_lattice_{};  // its inverse
  std::array<double, 3> lattice_reach_{};              // the lattice extent per unit of the grid's frame, per axis
  Box clip_{};                                         // lattice coordinates
  Box lattice_support_{};
  double max_density_ = 0, min_density_ = 0;
  std::array<int, 3> brick_counts_{};
  std::vector<Brick> bricks_;
};

}  // namespace stf::media
