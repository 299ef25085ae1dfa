#include "stf/core/grid.h"

#include "stf/core/fastmath.h"

#include <healpix_base.h>
#include <wcslib/prj.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace stf {

namespace {

constexpr double kDeg = 180.0 / kPi;

int parse_positive(const std::string& text, const std::string& spec) {
  int value = 0;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || value <= 0)
    throw std::invalid_argument("--grid '" + spec +
                                "' is not valid: expected csc:N or healpix:NSIDE with a "
                                "positive integer");
  return value;
}

// Solid angle of the spherical triangle (a, b, c), Van Oosterom & Strackee (1983): the
// atan2 form stays accurate for the tiny triangles of fine sub-division.
double triangle_solid_angle(const Vec3& a, const Vec3& b, const Vec3& c) {
  Vec3 bxc{b.y * c.z - b.z * c.y, b.z * c.x - b.x * c.z, b.x * c.y - b.y * c.x};
  double numer = dot(a, bxc);
  double denom = 1 + dot(a, b) + dot(b, c) + dot(c, a);
  return 2 * std::atan2(std::abs(numer), denom);
}

}  // namespace

void DirectionGrid::cells(const double* x, const double* y, const double* z, std::int64_t* out,
                          int n) const {
  for (int i = 0; i < n; ++i) out[i] = cell({x[i], y[i], z[i]});
}

namespace {

struct GridSpec {
  bool csc = false;
  int n = 0;  // cells per face edge, or NSIDE
};

GridSpec parse_grid(const std::string& spec) {
  auto colon = spec.find(':');
  std::string kind = spec.substr(0, colon);
  if (colon == std::string::npos || (kind != "csc" && kind != "healpix"))
    throw std::invalid_argument("--grid '" + spec + "' is not valid: expected csc:N or healpix:NSIDE");
  int value = parse_positive(spec.substr(colon + 1), spec);
  if (kind == "csc" && value > kMaxCubeN) throw std::invalid_argument("--grid csc:N allows 1 <= N <= " + std::to_string(kMaxCubeN) + ", got " + spec);
  if (kind == "healpix" && (value > kMaxNside || (value & (value - 1)) != 0))
    throw std::invalid_argument("--grid healpix:NSIDE needs a power of two 1.." + std::to_string(kMaxNside) + ", got " + spec);
  return {kind == "csc", value};
}

}  // namespace

std::int64_t grid_cell_count(const std::string& spec) {
  GridSpec g = parse_grid(spec);
  return (g.csc ? 6ll : 12ll) * g.n * g.n;
}

std::unique_ptr<DirectionGrid> make_grid(const std::string& spec) {
  GridSpec g = parse_grid(spec);
  if (g.csc) return std::make_unique<CscGrid>(g.n);
  return std::make_unique<HealpixGrid>(g.n);
}

// ---- CSC ----------------------------------------------------------------------------------

struct CscGrid::Projection {
  prjprm prj;
};

CscGrid::CscGrid(int n) : n_(n), prj_(std::make_unique<Projection>()) {
  prjini(&prj_->prj);
  if (cscset(&prj_->prj) != 0) throw std::runtime_error("WCSLIB cscset failed");
}

CscGrid::~CscGrid() = default;

std::string CscGrid::spec() const { return "csc:" + std::to_string(n_); }

// Face coordinates are uniform in cells, so halving N merges 2 x 2 blocks of rows and columns.
std::string CscGrid::coarser(int levels) const {
  return levels >= 0 && n_ % (1 << levels) == 0 ? "csc:" + std::to_string(n_ >> levels) : "";
}

std::vector<std::int64_t> CscGrid::parents(int levels) const {
  std::vector<std::int64_t> out(cell_count());
  const std::int64_t n = n_ >> levels;
  for (std::int64_t c = 0; c < cell_count(); ++c) {
    const std::int64_t face = c / (std::int64_t(n_) * n_), row = c / n_ % n_, col = c % n_;
    out[c] = (face * n + (row >> levels)) * n + (col >> levels);
  }
  return out;
}

void CscGrid::face_offset(int face, double& x0, double& y0) {
  static constexpr double kX[6] = {0, 0, 90, 180, 270, 0};
  static constexpr double kY[6] = {90, 0, 0, 0, 0, -90};
  x0 = kX[face];
  y0 = kY[face];
}

std::int64_t CscGrid::cell(const Vec3& d) const {
  // WCSLIB's native spherical coordinates: longitude phi, latitude theta, in degrees.
  double phi = std::atan2(d.y, d.x) * kDeg;
  double theta = std::atan2(d.z, std::hypot(d.x, d.y)) * kDeg;
  double x = 0, y = 0;
  int stat = 0;
  cscs2x(&prj_->prj, 1, 1, 1, 1, &phi, &theta, &x, &y, &stat);
  // Face from WCSLIB's plane position (its "sideways T" layout).
  int face;
  if (y > 45) {
    face = 0;
  } else if (y < -45) {
    face = 5;
  } else {
    if (x < -45) x += 360;
    face = 1 + std::clamp(int(std::floor((x + 45) / 90)), 0, 3);
  }
  double x0, y0;
  face_offset(face, x0, y0);
  double xf = (x - x0) / 45, yf = (y - y0) / 45;  // face coordinates in [-1, 1]
  int col = std::clamp(int(std::floor((xf + 1) * 0.5 * n_)), 0, n_ - 1);
  int row = std::clamp(int(std::floor((yf + 1) * 0.5 * n_)), 0, n_ - 1);
  return (std::int64_t(face) * n_ + row) * n_ + col;
}

Vec3 CscGrid::face_point(int face, double xf, double yf) const {
  double x0, y0;
  face_offset(face, x0, y0);
  double x = x0 + 45 * xf, y = y0 + 45 * yf, phi = 0, theta = 0;
  int stat = 0;
  cscx2s(&prj_->prj, 1, 1, 1, 1, &x, &y, &phi, &theta, &stat);
  double ct = std::cos(theta / kDeg);
  return normalize({ct * std::cos(phi / kDeg), ct * std::sin(phi / kDeg), std::sin(theta / kDeg)});
}

Vec3 CscGrid::centre(std::int64_t cell) const {
  int face = int(cell / (std::int64_t(n_) * n_));
  int rem = int(cell % (std::int64_t(n_) * n_));
  int row = rem / n_, col = rem % n_;
  return face_point(face, -1 + (2 * col + 1.0) / n_, -1 + (2 * row + 1.0) / n_);
}

// Sub-squares of each cell's face square, mapped through WCSLIB's inverse; each is measured
// as two spherical triangles (a geodesic quadrilateral, while the cell edges are curved).
// Neighbouring cells share sub-division corners, so the pieces tile each face without gaps.
CellQuadrature CscGrid::geodesic_subdivision(int level) const {
  const int s = 1 << level, m = n_ * s;  // sub-squares per cell edge, per face edge
  CellQuadrature q;
  q.per_cell = s * s;
  q.point.resize(std::size_t(cell_count()) * q.per_cell);
  q.weight.resize(q.point.size());
  std::vector<Vec3> v(std::size_t(m + 1) * (m + 1));
  for (int face = 0; face < 6; ++face) {
    for (int j = 0; j <= m; ++j)
      for (int i = 0; i <= m; ++i)
        v[j * (m + 1) + i] = face_point(face, -1 + 2.0 * i / m, -1 + 2.0 * j / m);
    for (int j = 0; j < m; ++j) {
      for (int i = 0; i < m; ++i) {
        const Vec3& a = v[j * (m + 1) + i];
        const Vec3& b = v[j * (m + 1) + i + 1];
        const Vec3& c = v[(j + 1) * (m + 1) + i + 1];
        const Vec3& d = v[(j + 1) * (m + 1) + i];
        std::int64_t id = (std::int64_t(face) * n_ + j / s) * n_ + i / s;
        std::size_t k = std::size_t(id) * q.per_cell + (j % s) * s + (i % s);
        q.weight[k] = triangle_solid_angle(a, b, c) + triangle_solid_angle(a, c, d);
        q.point[k] = face_point(face, -1 + (2 * i + 1.0) / m, -1 + (2 * j + 1.0) / m);
      }
    }
  }
  return q;
}

// Coarse sub-divisions follow the curved cell edges less closely (0.4% off in area for csc:10
// cells split once); the weights are rescaled to the cells' measured solid angles.
CellQuadrature CscGrid::quadrature(int level) const {
  CellQuadrature q = geodesic_subdivision(level);
  std::vector<double> omega = solid_angles();
  for (std::int64_t c = 0; c < cell_count(); ++c) {
    double sum = 0;
    for (int j = 0; j < q.per_cell; ++j) sum += q.weight[std::size_t(c) * q.per_cell + j];
    for (int j = 0; j < q.per_cell; ++j) q.weight[std::size_t(c) * q.per_cell + j] *= omega[c] / sum;
  }
  return q;
}

// The CSC is not equal-area: each cell's solid angle is summed over a sub-division fine
// enough (>= 64 sub-squares per face edge) that the curved cell edges are followed closely.
std::vector<double> CscGrid::solid_angles() const {
  int level = 0;
  while ((n_ << level) < 64) ++level;
  CellQuadrature q = geodesic_subdivision(level);
  std::vector<double> omega(cell_count(), 0.0);
  for (std::size_t k = 0; k < q.weight.size(); ++k) omega[k / q.per_cell] += q.weight[k];
  return omega;
}

// ---- HEALPix ------------------------------------------------------------------------------

struct HealpixGrid::Base {
  T_Healpix_Base<int64> base;
};

HealpixGrid::HealpixGrid(int nside)
    : nside_(nside), base_(std::make_unique<Base>(Base{T_Healpix_Base<int64>(nside, RING, SET_NSIDE)})) {}

HealpixGrid::~HealpixGrid() = default;

std::string HealpixGrid::spec() const { return "healpix:" + std::to_string(nside_); }

std::string HealpixGrid::coarser(int levels) const {
  return levels >= 0 && nside_ % (1 << levels) == 0 ? "healpix:" + std::to_string(nside_ >> levels) : "";
}

// In the NESTED scheme the 4^levels children of a cell are consecutive.
std::vector<std::int64_t> HealpixGrid::parents(int levels) const {
  T_Healpix_Base<int64> coarse(nside_ >> levels, NEST, SET_NSIDE);
  std::vector<std::int64_t> out(cell_count());
  for (std::int64_t c = 0; c < cell_count(); ++c) out[c] = coarse.nest2ring(base_->base.ring2nest(c) >> (2 * levels));
  return out;
}

std::int64_t HealpixGrid::cell(const Vec3& d) const {
  std::int64_t pix;
  cells(&d.x, &d.y, &d.z, &pix, 1);
  return pix;
}

// RING-scheme pixel of unit directions. Both the equatorial belt (|z| <= 2/3) and the polar
// caps are evaluated and the right one selected, so the loop has no branches. Near the poles
// 1 - |z| is taken as rho^2 / (1 + |z|), which does not cancel.
constexpr double kBelowFour = 4 - 4 * std::numeric_limits<double>::epsilon() / 2;

void HealpixGrid::cells(const double* x, const double* y, const double* z, std::int64_t* out,
                        int n) const {
  const double ns = nside_;
  const std::int32_t nside = nside_, nl4 = 4 * nside_, ncap = 2 * nside_ * (nside_ - 1);
  const std::int32_t npix = 12 * nside_ * nside_;
  for (int i = 0; i < n; ++i) {
    double zi = z[i], za = std::abs(zi);
    double rho2 = x[i] * x[i] + y[i] * y[i];
    double tt = fast_atan2(y[i], x[i]) * (2 / kPi);  // in (-2, 2]
    // In [0, 4). Just below phi = 0, tt + 4 rounds up to 4: that is the last pixel of the ring,
    // not the first (wrapping it to 0 sent every direction a hair below the x-z plane to the
    // cell above it).
    tt = std::min(tt < 0 ? tt + 4 : tt, kBelowFour);
    // Equatorial belt. 32-bit integers (NSIDE <= 8192 keeps every index below 2^31; stf allows up to 2048) let the
    // loop vectorise.
    double t1 = ns * (0.5 + tt), t2 = ns * zi * 0.75;
    std::int32_t jp = std::int32_t(t1 - t2), jm = std::int32_t(t1 + t2);
    std::int32_t ir = nside + 1 + jp - jm;
    std::int32_t kshift = 1 - (ir & 1);
    std::int32_t ip = ((jp + jm - nside + kshift + 1 + 2 * nl4) >> 1) & (nl4 - 1);
    std::int32_t belt = ncap + (ir - 1) * nl4 + ip;
    // Polar caps: tmp = nside sqrt(3 (1 - |z|)).
    double tp = tt - double(std::int32_t(tt));
    double tmp = ns * std::sqrt(3 * rho2 / (1 + za));
    std::int32_t pjp = std::int32_t(tp * tmp), pjm = std::int32_t((1 - tp) * tmp);
    std::int32_t pir = pjp + pjm + 1;
    std::int32_t pip = std::min(std::int32_t(tt * double(pir)), 4 * pir - 1);
    std::int32_t cap = zi > 0 ? 2 * pir * (pir - 1) + pip : npix - 2 * pir * (pir + 1) + pip;
    out[i] = za <= 2.0 / 3.0 ? belt : cap;
  }
}

Vec3 HealpixGrid::centre(std::int64_t cell) const {
  vec3 v = base_->base.pix2vec(cell);
  return {v.x, v.y, v.z};
}

// Sub-cells are the NESTED children at NSIDE 2^level: an exact equal-area partition.
CellQuadrature HealpixGrid::quadrature(int level) const {
  const std::int64_t fine_nside = std::int64_t(nside_) << level;
  T_Healpix_Base<int64> fine(fine_nside, NEST, SET_NSIDE);
  CellQuadrature q;
  q.per_cell = 1 << (2 * level);
  q.point.resize(std::size_t(cell_count()) * q.per_cell);
  q.weight.assign(q.point.size(), 4 * kPi / double(fine.Npix()));
  for (std::int64_t c = 0; c < cell_count(); ++c) {
    std::int64_t nest = base_->base.ring2nest(c);
    for (int j = 0; j < q.per_cell; ++j) {
      vec3 v = fine.pix2vec(nest * q.per_cell + j);
      q.point[std::size_t(c) * q.per_cell + j] = {v.x, v.y, v.z};
    }
  }
  return q;
}

std::vector<double> HealpixGrid::solid_angles() const {
  return std::vector<double>(cell_count(), 4 * kPi / double(cell_count()));
}

}  // namespace stf
