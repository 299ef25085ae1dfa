#include "alpha_marginal.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "stf/quadrature.h"

namespace stf::fit {

namespace {

constexpr int kMarginalKnots = 24;
constexpr int kDegree = 3;
constexpr int kBasis = kMarginalKnots + kDegree - 1;  // clamped cubic B-splines on the knots
constexpr int kNodes = 8;                             // Gauss-Legendre nodes per sub-bin

std::vector<double> clamped_knots() {
  std::vector<double> t(kDegree, 0.0);
  for (int k = 0; k < kMarginalKnots; ++k) {
    const double s = double(k) / (kMarginalKnots - 1);
    t.push_back(std::numbers::pi * s * s);
  }
  t.insert(t.end(), kDegree, std::numbers::pi);
  return t;
}

// The kDegree + 1 basis functions that do not vanish at x, the first of them `first`
// (Cox-de Boor, built up degree by degree).
void basis_at(const std::vector<double>& t, double x, int& first, double (&value)[kDegree + 1]) {
  int span = kDegree;
  while (span + 1 < kBasis && t[std::size_t(span + 1)] <= x) ++span;
  double left[kDegree + 1], right[kDegree + 1];
  value[0] = 1;
  for (int j = 1; j <= kDegree; ++j) {
    left[j] = x - t[std::size_t(span + 1 - j)];
    right[j] = t[std::size_t(span + j)] - x;
    double saved = 0;
    for (int r = 0; r < j; ++r) {
      const double share = value[r] / (right[r + 1] + left[j - r]);
      value[r] = saved + right[r + 1] * share;
      saved = left[j - r] * share;
    }
    value[j] = saved;
  }
  first = span - kDegree;
}

// The expected count of sub-bin j is the integral of exp(basis . beta) over its area:
// node q of sub-bin j sits at alpha with basis row basis.row(j kNodes + q) and area weight.
struct Design {
  Eigen::MatrixXd basis;  // [sub-bins * kNodes, kBasis]
  Eigen::VectorXd area;   // [sub-bins * kNodes]
  Eigen::MatrixXd roughness;  // D^T D, D the second differences of the coefficients
};

Design design(const Table& t) {
  const std::vector<double> knots = clamped_knots();
  const int subs = t.alpha_bins * t.sub_bins;
  Design d{Eigen::MatrixXd::Zero(subs * kNodes, kBasis), Eigen::VectorXd::Zero(subs * kNodes), {}};
  int row = 0;
  for (int b = 0; b < t.alpha_bins; ++b) {
    const double c0 = std::cos(t.alpha_edges[std::size_t(b)]), c1 = std::cos(t.alpha_edges[std::size_t(b) + 1]);
    for (int k = 0; k < t.sub_bins; ++k) {
      // Sub-bins split the bin's area, which is linear in cos(alpha).
      const double lo = c0 + t.sub_edge(b, k) * (c1 - c0), hi = c0 + t.sub_edge(b, k + 1) * (c1 - c0);
      const double mid = 0.5 * (lo + hi), half = 0.5 * (lo - hi);
      for (int i = 0; i < kNodes; ++i, ++row) {
        const double node = kGauss8Node[i % 4] * (i < 4 ? -1 : 1);
        const double alpha = std::acos(std::clamp(mid + half * node, -1.0, 1.0));
        int first = 0;
        double value[kDegree + 1];
        basis_at(knots, alpha, first, value);
        for (int j = 0; j <= kDegree; ++j) d.basis(row, first + j) = value[j];
        d.area(row) = 2 * std::numbers::pi * std::abs(half) * kGauss8Weight[i % 4];
      }
    }
  }
  Eigen::MatrixXd second = Eigen::MatrixXd::Zero(kBasis - 2, kBasis);
  for (int i = 0; i < kBasis - 2; ++i) second(i, i) = 1, second(i, i + 1) = -2, second(i, i + 2) = 1;
  d.roughness = second.transpose() * second;
  return d;
}

Eigen::VectorXd sub_bin_means(const Design& d, const Eigen::VectorXd& beta) {
  const Eigen::VectorXd density = (d.basis * beta).array().min(700.0).exp().matrix();
  return density.cwiseProduct(d.area).reshaped(kNodes, d.area.size() / kNodes).colwise().sum().transpose();
}

double poisson_nll(const Eigen::VectorXd& counts, const Eigen::VectorXd& mean) {
  double nll = 0;
  for (Eigen::Index j = 0; j < counts.size(); ++j)
    nll += mean(j) - (counts(j) > 0 ? counts(j) * std::log(std::max(mean(j), 1e-300)) : 0.0);
  return nll;
}

// Penalised maximum likelihood by Fisher scoring with step halving, from `beta`.
Eigen::VectorXd fit_log_density(const Design& d, const Eigen::VectorXd& counts, double penalty, Eigen::VectorXd beta) {
  const Eigen::MatrixXd P = penalty * d.roughness;
  auto objective = [&](const Eigen::VectorXd& b, const Eigen::VectorXd& mean) { return poisson_nll(counts, mean) + 0.5 * b.dot(P * b); };
  const Eigen::Index subs = counts.size();
  for (int iteration = 0; iteration < 200; ++iteration) {
    const Eigen::VectorXd density = (d.basis * beta).array().min(700.0).exp().matrix().cwiseProduct(d.area);
    Eigen::MatrixXd dmean = Eigen::MatrixXd::Zero(subs, kBasis);  // d mean_j / d beta
    for (Eigen::Index j = 0; j < subs; ++j)
      dmean.row(j) = density.segment(j * kNodes, kNodes).transpose() * d.basis.middleRows(j * kNodes, kNodes);
    const Eigen::VectorXd mean = dmean.rowwise().sum().cwiseMax(1e-300);
    // dmean.rowwise().sum() is sum_i dmean_ji = mean_j because the B-splines sum to 1.
    const Eigen::VectorXd gradient = dmean.transpose() * (counts.cwiseQuotient(mean) - Eigen::VectorXd::Ones(subs)) - P * beta;
    const Eigen::MatrixXd fisher = dmean.transpose() * mean.cwiseInverse().asDiagonal() * dmean + P;
    const Eigen::VectorXd step = fisher.ldlt().solve(gradient);
    if (!step.allFinite()) break;
    // Half the Newton decrement is the gain a full step promises: below 1e-9 nats there is
    // nothing left to gain that a double could see in an objective of millions of nats.
    if (gradient.dot(step) < 2e-9) break;
    const double before = objective(beta, mean);
    double scale = 1;
    auto at = [&](double a) { const Eigen::VectorXd b = beta + a * step; return objective(b, sub_bin_means(d, b)); };
    while (!(at(scale) <= before) && scale > 1e-6) scale *= 0.5;
    if (!(scale > 1e-6)) break;  // no step lowers it any more: converged to rounding
    beta += scale * step;
  }
  return beta;
}

}  // namespace

AlphaMarginal smooth_alpha_marginal(const Table& t) {
  AlphaMarginal m;
  if (t.sub_bins <= 0 || !t.once_tallied) return m;
  const Eigen::Index subs = Eigen::Index(t.alpha_bins) * t.sub_bins;
  Eigen::VectorXd half[2] = {Eigen::VectorXd::Zero(subs), Eigen::VectorXd::Zero(subs)};
  for (int h = 0; h < 2; ++h)
    for (Eigen::Index j = 0; j < subs; ++j) half[h](j) = t.multiple_sub_half[std::size_t(h)][std::size_t(j)];
  const Eigen::VectorXd both = half[0] + half[1];
  if (!(half[0].sum() > 0 && half[1].sum() > 0)) return m;
  const Design d = design(t);
  // Each half fitted with the other's counts held out; penalties from weak to strong, each fit
  // starting from the last.
  Eigen::VectorXd beta[2];
  for (int h = 0; h < 2; ++h) beta[h] = Eigen::VectorXd::Constant(kBasis, std::log(half[h].sum() / (4 * std::numbers::pi)));
  double best = std::numeric_limits<double>::infinity();
  for (int k = 0; k <= 12; ++k) {  // penalties 1 to 1e6 in half decades
    const double penalty = std::pow(10.0, 0.5 * k);
    double nll = 0;
    for (int h = 0; h < 2; ++h) {
      beta[h] = fit_log_density(d, half[h], penalty, beta[h]);
      nll += poisson_nll(half[1 - h], sub_bin_means(d, beta[h]));
    }
    if (nll < best) best = nll, m.penalty = penalty;
  }
  const Eigen::VectorXd start = Eigen::VectorXd::Constant(kBasis, std::log(both.sum() / (4 * std::numbers::pi)));
  Eigen::VectorXd mean = sub_bin_means(d, fit_log_density(d, both, m.penalty, start));
  mean *= both.sum() / mean.sum();  // the unpenalised constant already keeps the total; exactly
  m.sub_escapes.assign(mean.data(), mean.data() + subs);
  for (int b = 0; b < t.alpha_bins; ++b)
    m.bin_escapes.push_back(mean.segment(Eigen::Index(b) * t.sub_bins, t.sub_bins).sum());
  return m;
}

}  // namespace stf::fit
