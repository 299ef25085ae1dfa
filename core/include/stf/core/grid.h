// Direction grids: a partition of the sphere of directions into cells with known solid
// angles. `csc:N` is the thesis's COBE sky cube (section 3.3.1) on WCSLIB's CSC projection;
// `healpix:NSIDE` is HEALPix (RING order): equal-area cells, no special cells at the poles.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "stf/core/geometry.h"

namespace stf {

// Sub-cells of every cell: `per_cell` consecutive points per cell (cell-major), each the
// centre direction and solid angle of a sub-cell; the sub-cells of a cell partition it.
struct CellQuadrature {
  int per_cell = 1;
  std::vector<Vec3> point;
  std::vector<double> weight;
};

class DirectionGrid {
 public:
  virtual ~DirectionGrid() = default;
  // The spec this grid was made from, e.g. "csc:45" or "healpix:16".
  virtual std::string spec() const = 0;
  virtual std::int64_t cell_count() const = 0;
  // The cell containing a unit direction. Every direction maps to exactly one cell.
  virtual std::int64_t cell(const Vec3& direction) const = 0;
  // The cells of n unit directions given as coordinate arrays: the same as cell() on each,
  // in one call so that the walk bins a batch of escapes without a virtual call apiece.
  virtual void cells(const double* x, const double* y, const double* z, std::int64_t* out,
                     int n) const;
  // Unit vector at the cell's centre.
  virtual Vec3 centre(std::int64_t cell) const = 0;
  // Solid angle of every cell (steradians); they sum to 4 pi.
  virtual std::vector<double> solid_angles() const = 0;
  // Each cell split 2^level times along each side: for integrating a density over cells.
  virtual CellQuadrature quadrature(int level) const = 0;
  // The grid whose cells are unions of 4^levels of these cells (HEALPix NSIDE or the cube's
  // N halved `levels` times), or "" when the resolution does not halve that often.
  virtual std::string coarser(int levels) const = 0;
  // For every cell, the cell of coarser(levels) that holds it.
  virtual std::vector<std::int64_t> parents(int levels) const = 0;
};

// Parses "csc:N" (1 <= N <= kMaxCubeN) or "healpix:NSIDE" (a power of two, 1 <= NSIDE <= kMaxNside).
// Throws std::invalid_argument with a message naming what is allowed.
std::unique_ptr<DirectionGrid> make_grid(const std::string& spec);
// The finest grids stf makes: HEALPix NSIDE and the cube's N.
inline constexpr int kMaxNside = 2048, kMaxCubeN = 1024;
// The cell count of a grid spec, checked as make_grid checks it, without building the grid.
std::int64_t grid_cell_count(const std::string& spec);

// The thesis's cube layout: cell index = face * N^2 + row * N + column, rows and columns
// counted from the bottom-left of each face in WCSLIB's (x, y) plane. Faces follow WCSLIB:
// 0 = +z (theta = 90 deg), 1 = +x, 2 = +y, 3 = -x, 4 = -y, 5 = -z.
class CscGrid final : public DirectionGrid {
 public:
  explicit CscGrid(int n);
  ~CscGrid() override;
  std::string spec() const override;
  std::int64_t cell_count() const override { return 6ll * n_ * n_; }
  std::int64_t cell(const Vec3& direction) const override;
  Vec3 centre(std::int64_t cell) const override;
  std::vector<double> solid_angles() const override;
  CellQuadrature quadrature(int level) const override;
  std::string coarser(int levels) const override;
  std::vector<std::int64_t> parents(int levels) const override;

  int n() const { return n_; }
  // Centre of `face` in WCSLIB's projection plane, in degrees.
  static void face_offset(int face, double& x0, double& y0);
  // Unit direction at face coordinates (xf, yf) in [-1, 1]^2, through WCSLIB's inverse.
  Vec3 face_point(int face, double xf, double yf) const;

 private:
  CellQuadrature geodesic_subdivision(int level) const;
  int n_;
  struct Projection;
  std::unique_ptr<Projection> prj_;
};

// Cells are found by stf's own branch-free RING-scheme lookup (Gorski et al. 2005, eq. 4-9 of
// the HEALPix primer) with a polynomial atan2 accurate to ~1e-8 rad, several times faster than
// healpix_cxx's vec2pix; it agrees with vec2pix except within ~1e-8 rad of a cell edge
// (tested). Centres come from healpix_cxx.
class HealpixGrid final : public DirectionGrid {
 public:
  explicit HealpixGrid(int nside);
  ~HealpixGrid() override;
  std::string spec() const override;
  std::int64_t cell_count() const override { return 12ll * nside_ * nside_; }
  std::int64_t cell(const Vec3& direction) const override;
  void cells(const double* x, const double* y, const double* z, std::int64_t* out,
             int n) const override;
  Vec3 centre(std::int64_t cell) const override;
  std::vector<double> solid_angles() const override;
  CellQuadrature quadrature(int level) const override;
  std::string coarser(int levels) const override;
  std::vector<std::int64_t> parents(int levels) const override;
  int nside() const { return nside_; }

 private:
  int nside_;
  struct Base;
  std::unique_ptr<Base> base_;
};

}  // namespace stf
