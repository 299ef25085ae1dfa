#include "lobe_deviance.h"

#include <algorithm>
#include <cmath>
#include <tuple>
#include <utility>

namespace stf::fit {

namespace {

// Signed deviance residual r of count n against expectation mu, and d r / d mu: sum r^2 is
// the Poisson deviance, so least squares on r is maximum likelihood.
std::pair<double, double> deviance_residual(double n, double mu) {
  mu = std::max(mu, 1e-300);
  if (n <= 0) return {-std::sqrt(2 * mu), -1 / std::sqrt(2 * mu)};
  const double d = 2 * (n * std::log(n / mu) - (n - mu));
  if (d < 1e-12 * n) return {(n - mu) / std::sqrt(n), -1 / std::sqrt(n)};  // mu ~ n: r ~ (n - mu) / sqrt(n)
  const double root = std::sqrt(d);
  return {n > mu ? root : -root, -std::abs(mu - n) / (mu * root)};
}

}  // namespace

// One evaluation's lobes: weights (softmax of the clamped logits), which parameters are inside
// their bounds, and per lobe its masses on the rows and totals over the sphere, with their
// derivatives by log kappa and by the mean when asked for.
struct PoissonDeviance::Lobes {
  std::vector<double> w, share;  // p_row = sum_k share_k mass_k,row
  std::vector<char> free_logit, free_kappa;
  std::vector<double> mass, d_theta, d_mean;
  std::vector<double> total, total_theta, total_mean;
};

PoissonDeviance::PoissonDeviance(LobeIntegrator cells, int lobes, double min_kappa, double max_kappa)
    : cells_(std::move(cells)), lobes_(lobes), min_log_kappa_(std::log(min_kappa)),
      max_log_kappa_(std::log(max_kappa)) {
  set_num_residuals(cells_.rows() + 1);
  mutable_parameter_block_sizes()->push_back(lobes);
  mutable_parameter_block_sizes()->push_back(lobes);
  for (int k = 0; k < lobes; ++k) mutable_parameter_block_sizes()->push_back(3);
}

std::vector<double> lobe_weights(std::vector<double> logits) {
  for (double& l : logits) l = std::clamp(l, -kMaxLogit, kMaxLogit);
  const double max_logit = *std::max_element(logits.begin(), logits.end());
  double sum = 0;
  for (double& l : logits) sum += (l = std::exp(l - max_logit));
  for (double& w : logits) w /= sum;
  return logits;
}

PoissonDeviance::Lobes PoissonDeviance::integrate(double const* const* params, bool derivatives) const {
  const int K = lobes_, rows = cells_.rows();
  Lobes l;
  std::vector<double> logit(K), log_kappa(K);
  l.free_logit.resize(K), l.free_kappa.resize(K);
  for (int k = 0; k < K; ++k) {
    logit[k] = std::clamp(params[0][k], -kMaxLogit, kMaxLogit), l.free_logit[k] = logit[k] == params[0][k];
    log_kappa[k] = std::clamp(params[1][k], min_log_kappa_, max_log_kappa_), l.free_kappa[k] = log_kappa[k] == params[1][k];
  }
  l.w = lobe_weights(logit);

  // Levenberg-Marquardt asks for the residuals alone at every trial step (about half the
  // calls): the derivatives are then not accumulated.
  l.mass.assign(std::size_t(K) * rows, 0), l.d_theta.assign(derivatives ? l.mass.size() : 0, 0);
  l.d_mean.assign(derivatives ? 3 * l.mass.size() : 0, 0);
  l.total.assign(K, 0), l.total_theta.assign(K, 0), l.total_mean.assign(3 * K, 0);
  LobeIntegrator::CopyScratch scratch = cells_.make_scratch(derivatives);
  for (int k = 0; k < K; ++k) {
    const double kappa = std::exp(log_kappa[k]);
    const Vec3 mean = normalize({params[2 + k][0], params[2 + k][1], params[2 + k][2]});
    const std::size_t at = std::size_t(k) * rows;
    cells_.integrate_bin_lobe(mean, kappa,
                              {&l.mass[at], derivatives ? &l.d_theta[at] : nullptr,
                               derivatives ? &l.d_mean[3 * at] : nullptr, &l.total[k], &l.total_theta[k],
                               &l.total_mean[3 * k]},
                              scratch);
  }
  // A hemispherical lobe turned wholly below the bin's tangent planes has no mass at all: it
  // then adds nothing and has no gradient (its masses and their derivatives are all 0, so a
  // total of 1 keeps 0 / 0 out).
  for (double& t : l.total)
    if (!(t > 1e-150)) t = 1;
  l.share.resize(K);
  for (int k = 0; k < K; ++k) l.share[k] = l.w[k] / l.total[k];
  return l;
}

bool PoissonDeviance::Evaluate(double const* const* params, double* residuals, double** jacobians) const {
  const Lobes l = integrate(params, jacobians != nullptr);
  const int K = lobes_, rows = cells_.rows();
  const std::vector<double>& count = cells_.row_counts();
  const double escapes = cells_.escapes();
  // Probabilities, residuals, d residual / d mu.
  std::vector<double> p(rows, 0), dr(rows + 1);
  double p_rest = 1;
  for (int row = 0; row < rows; ++row) {
    for (int k = 0; k < K; ++k) p[row] += l.share[k] * l.mass[std::size_t(k) * rows + row];
    p_rest -= p[row];
    std::tie(residuals[row], dr[row]) = deviance_residual(count[row], escapes * p[row]);
  }
  std::tie(residuals[rows], dr[rows]) = deviance_residual(0, escapes * std::max(p_rest, 0.0));
  if (jacobians) jacobian(l, p, dr, p_rest, jacobians);
  return true;
}

void PoissonDeviance::jacobian(const Lobes& l, const std::vector<double>& p, const std::vector<double>& dr,
                               double p_rest, double** jacobians) const {
  const int K = lobes_, rows = cells_.rows();
  const double escapes = cells_.escapes();
  // d p_row / d parameter, then the chain rule; the empty-cells residual moves opposite to
  // the sum of the others.
  auto fill = [&](int block, int width, auto dp) {
    if (!jacobians[block]) return;
    double* J = jacobians[block];
    std::vector<double> rest(width, 0);
    for (int row = 0; row < rows; ++row) {
      for (int col = 0; col < width; ++col) {
        double d = dp(row, col);
        J[row * width + col] = dr[row] * escapes * d;
        rest[col] -= d;
      }
    }
    for (int col = 0; col < width; ++col) J[rows * width + col] = p_rest > 0 ? dr[rows] * escapes * rest[col] : 0;
  };
  // Per lobe, p_row = w_k mass_row / total: its derivatives are (w_k / total) d mass_row -
  // (w_k d total / total^2) mass_row, with the quotients taken once per lobe.
  std::vector<double> theta_pull(K), mean_pull(3 * std::size_t(K));
  for (int k = 0; k < K; ++k) {
    theta_pull[k] = l.share[k] * l.total_theta[k] / l.total[k];
    for (int axis = 0; axis < 3; ++axis) mean_pull[3 * k + axis] = l.share[k] * l.total_mean[3 * k + axis] / l.total[k];
  }
  fill(0, K, [&](int row, int j) {
    return l.free_logit[j] ? l.share[j] * l.mass[std::size_t(j) * rows + row] - l.w[j] * p[row] : 0.0;
  });
  fill(1, K, [&](int row, int k) {
    std::size_t r = std::size_t(k) * rows + row;
    return l.free_kappa[k] ? l.share[k] * l.d_theta[r] - theta_pull[k] * l.mass[r] : 0.0;
  });
  for (int k = 0; k < K; ++k) {
    fill(2 + k, 3, [&](int row, int axis) {
      std::size_t r = std::size_t(k) * rows + row;
      return l.share[k] * l.d_mean[3 * r + axis] - mean_pull[3 * k + axis] * l.mass[r];
    });
  }
}

TurnedDeviance::TurnedDeviance(std::unique_ptr<PoissonDeviance> inner, int lobes, double angle, double weight,
                               bool sloped, double offset)
    : inner_(std::move(inner)), lobes_(lobes), angle_(angle), scale_(std::sqrt(weight)), sloped_(sloped),
      offset_(offset) {
  set_num_residuals(inner_->num_residuals());
  *mutable_parameter_block_sizes() = inner_->parameter_block_sizes();
  if (sloped_)
    for (int i = 0; i < 3; ++i) mutable_parameter_block_sizes()->push_back(lobes);
}

bool TurnedDeviance::Evaluate(double const* const* params, double* residuals, double** jacobians) const {
  const std::size_t K = std::size_t(lobes_);
  std::vector<double> turned(3 * K), logits(params[0], params[0] + K), log_kappa(params[1], params[1] + K);
  std::vector<double> c(K, std::cos(angle_)), s(K, std::sin(angle_));
  const double* const* slope = sloped_ ? params + 2 + K : nullptr;  // logits, log kappas, turns
  for (std::size_t k = 0; k < K && slope; ++k) {
    logits[k] += offset_ * slope[0][k], log_kappa[k] += offset_ * slope[1][k];
    c[k] = std::cos(angle_ + offset_ * slope[2][k]), s[k] = std::sin(angle_ + offset_ * slope[2][k]);
  }
  std::vector<const double*> p{logits.data(), log_kappa.data()};
  for (std::size_t k = 0; k < K; ++k) {
    const double* m = params[2 + k];
    double* t = &turned[3 * k];
    t[0] = c[k] * m[0] + s[k] * m[2], t[1] = m[1], t[2] = -s[k] * m[0] + c[k] * m[2];
    p.push_back(t);
  }
  // The slopes' derivatives come from the inner ones, needed even where a block is held.
  const std::size_t rows = std::size_t(num_residuals());
  std::vector<std::vector<double>> own(jacobians && slope ? 2 + K : 0);
  std::vector<double*> inner_jacobians;
  for (std::size_t i = 0; jacobians && i < 2 + K; ++i) {
    inner_jacobians.push_back(jacobians[i]);
    if (!jacobians[i] && slope) own[i].resize(rows * (i < 2 ? K : 3)), inner_jacobians[i] = own[i].data();
  }
  if (!inner_->Evaluate(p.data(), residuals, jacobians ? inner_jacobians.data() : nullptr)) return false;
  for (std::size_t r = 0; r < rows; ++r) residuals[r] *= scale_;
  if (!jacobians) return true;
  for (std::size_t block = 0; block < 2; ++block) {
    double* J = inner_jacobians[block];
    if (!J) continue;
    for (std::size_t i = 0; i < rows * K; ++i) J[i] *= scale_;
    if (slope && jacobians[2 + K + block])  // d / d slope = offset d / d (the moved parameter)
      for (std::size_t i = 0; i < rows * K; ++i) jacobians[2 + K + block][i] = offset_ * J[i];
  }
  for (std::size_t k = 0; k < K; ++k) {
    double* J = inner_jacobians[2 + k];
    if (!J) continue;
    const double* m = params[2 + k];
    // d (R m) / d turn = R' m with R' = [[-s, 0, c], [0, 0, 0], [-c, 0, -s]].
    const double tx = -s[k] * m[0] + c[k] * m[2], tz = -c[k] * m[0] - s[k] * m[2];
    double* turn = slope ? jacobians[2 + K + 2] : nullptr;
    for (std::size_t r = 0; r < rows; ++r) {
      double* row = J + 3 * r;
      const double jx = row[0], jy = row[1], jz = row[2];  // times R_y = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
      if (turn) turn[r * K + k] = scale_ * offset_ * (jx * tx + jz * tz);
      row[0] = scale_ * (jx * c[k] - jz * s[k]), row[1] = scale_ * jy, row[2] = scale_ * (jx * s[k] + jz * c[k]);
    }
  }
  return true;
}

}  // namespace stf::fit
