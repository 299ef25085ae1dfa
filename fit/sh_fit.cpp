#include "sh_fit.h"

#include <Eigen/Dense>
#include <alm.h>
#include <alm_healpix_tools.h>
#include <healpix_map.h>

#include <cmath>

#include "stf/sh.h"

namespace stf::fit {

struct ShProjector::Impl {
  std::vector<double> solid_angle;
  int nside = 0;                       // > 0: HEALPix path
  Eigen::MatrixXd cell_basis;          // [cells, count]: basis averaged over each cell
  Eigen::LDLT<Eigen::MatrixXd> normal;  // of B^T W B, W = solid angles
};

ShProjector::ShProjector(const DirectionGrid& grid, int band_limit)
    : band_limit_(band_limit), impl_(std::make_unique<Impl>()) {
  impl_->solid_angle = grid.solid_angles();
  if (auto* healpix = dynamic_cast<const HealpixGrid*>(&grid)) {
    impl_->nside = healpix->nside();
    return;
  }
  const int count = sh_count(band_limit);
  CellQuadrature q = grid.quadrature(2);
  std::vector<double> basis = sh_basis_at(q, band_limit);
  const std::int64_t cells = grid.cell_count();
  impl_->cell_basis.setZero(cells, count);
  for (std::size_t k = 0; k < q.point.size(); ++k)
    for (int i = 0; i < count; ++i) impl_->cell_basis(k / q.per_cell, i) += q.weight[k] * basis[k * count + i];
  for (std::int64_t c = 0; c < cells; ++c) impl_->cell_basis.row(c) /= impl_->solid_angle[c];
  Eigen::VectorXd w = Eigen::Map<const Eigen::VectorXd>(impl_->solid_angle.data(), cells);
  Eigen::MatrixXd normal = impl_->cell_basis.transpose() * w.asDiagonal() * impl_->cell_basis;
  normal.diagonal().array() += 1e-12;  // keeps band limits beyond the grid's resolution solvable
  impl_->normal.compute(normal);
}

ShProjector::~ShProjector() = default;

std::vector<double> ShProjector::project(const std::vector<double>& counts) const {
  const std::size_t cells = counts.size();
  double total = 0;
  for (double n : counts) total += n;
  std::vector<double> density(cells);
  for (std::size_t c = 0; c < cells; ++c) density[c] = counts[c] / (total * impl_->solid_angle[c]);
  const int L = band_limit_;
  std::vector<double> out(sh_count(L), 0.0);
  if (impl_->nside > 0) {
    Healpix_Map<double> map(impl_->nside, RING, SET_NSIDE);
    for (std::size_t c = 0; c < cells; ++c) map[int(c)] = density[c];
    Alm<xcomplex<double>> alm(L, L);
    map2alm_iter(map, alm, 3);
    // healpix_cxx's complex Y_lm carry the Condon-Shortley phase (-1)^m; stf's real basis
    // does not: Y^c_lm = sqrt2 N P cos(m phi), Y^s_lm = sqrt2 N P sin(m phi).
    for (int l = 0; l <= L; ++l) {
      out[l * l + l] = alm(l, 0).real();
      for (int m = 1; m <= l; ++m) {
        double sign = (m % 2) ? -1.0 : 1.0;
        out[l * l + l + m] = sign * std::sqrt(2.0) * alm(l, m).real();
        out[l * l + l - m] = -sign * std::sqrt(2.0) * alm(l, m).imag();
      }
    }
    return out;
  }
  Eigen::VectorXd w = Eigen::Map<const Eigen::VectorXd>(impl_->solid_angle.data(), cells);
  Eigen::VectorXd f = Eigen::Map<const Eigen::VectorXd>(density.data(), cells);
  Eigen::VectorXd a = impl_->normal.solve(impl_->cell_basis.transpose() * (w.asDiagonal() * f));
  for (int i = 0; i < sh_count(L); ++i) out[i] = a[i];
  return out;
}

void smooth_sh(std::vector<double>& c, int L, const ShSmoothing& smoothing) {
  for (int l = 1; l <= L; ++l) {
    double x = kPi * l / (L + 1);
    double factor = (smoothing.lanczos ? std::sin(x) / x : 1.0) * std::exp(-smoothing.t * l * (l + 1));
    for (int m = -l; m <= l; ++m) c[l * l + l + m] *= factor;
  }
}

std::vector<double> sh_basis_at(const CellQuadrature& q, int L) {
  const int count = sh_count(L);
  std::vector<double> basis(q.point.size() * count);
  for (std::size_t k = 0; k < q.point.size(); ++k) sh_basis(L, q.point[k], &basis[k * count]);
  return basis;
}

std::vector<double> clamped_sh_cell_probabilities(const std::vector<double>& c,
                                                  const std::vector<double>& basis,
                                                  const CellQuadrature& q) {
  const std::size_t count = c.size(), cells = q.point.size() / q.per_cell;
  std::vector<double> p(cells, 0.0);
  double total = 0;
  for (std::size_t k = 0; k < q.point.size(); ++k) {
    double v = 0;
    for (std::size_t i = 0; i < count; ++i) v += c[i] * basis[k * count + i];
    double m = q.weight[k] * std::max(v, 0.0);
    p[k / q.per_cell] += m;
    total += m;
  }
  for (double& v : p) v = total > 0 ? v / total : 1.0 / double(cells);
  return p;
}

void compress_across_alpha(StfModel& m, const std::vector<double>& escapes) {
  const int bins = m.bins(), count = sh_count(m.band_limit), n = m.alpha_degree + 1;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(bins, n), Y = Eigen::MatrixXd::Zero(bins, count);
  for (int b = 0; b < bins; ++b) {
    double x = std::cos(0.5 * (m.alpha_edges[b] + m.alpha_edges[b + 1]));
    double w = m.status[b] == BinStatus::kFitted ? std::sqrt(escapes[b]) : 0.0;
    for (int j = 0; j < n; ++j) A(b, j) = w * std::cos(j * std::acos(x));  // T_j(x)
    for (int i = 0; i < count; ++i) Y(b, i) = w * m.sh[std::size_t(b) * count + i];
  }
  Eigen::MatrixXd C = A.colPivHouseholderQr().solve(Y);  // [n, count]
  m.sh_chebyshev.clear();
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < count; ++i) m.sh_chebyshev.push_back(C(j, i));
  for (int b = 0; b < bins; ++b) {
    double x = std::cos(0.5 * (m.alpha_edges[b] + m.alpha_edges[b + 1]));
    for (int i = 0; i < count; ++i) {
      double v = 0;
      for (int j = 0; j < n; ++j) v += C(j, i) * std::cos(j * std::acos(x));
      m.sh[std::size_t(b) * count + i] = v;
    }
  }
  m.rebuild_sh_tables();
}

}  // namespace stf::fit
