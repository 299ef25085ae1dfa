#include "stf/once_scattered.h"

#include "stf/math.h"
#include "stf/quadrature.h"

namespace stf {

namespace {

constexpr int kSCells = 64, kUCells = 64;


}  // namespace

std::vector<double> OnceScattered::s_edges() {
  // Cells crowd quadratically at both ends (Chebyshev spacing; the end cells are 6e-4 wide):
  // near the centre for the e^{-2 tau s} of backward scattering up to tau ~ 1000, near the
  // surface for the paths that leave sideways, whose length s + sqrt(1 - s^2) has a square root
  // at s = 1.
  std::vector<double> e(kSCells + 1);
  for (int i = 0; i <= kSCells; ++i) e[i] = 0.5 * (1 - std::cos(kPi * i / kSCells));
  e.front() = 0, e.back() = 1;
  return e;
}

std::vector<double> OnceScattered::u_edges() {
  std::vector<double> e(kUCells + 1);
  for (int j = 0; j <= kUCells; ++j) e[j] = double(j) / kUCells;
  return e;
}

double once_scattered_probability(double tau, double g) {
  const HgParams<double> hg = HgParams<double>::make(g);
  const std::vector<double> se = OnceScattered::s_edges(), ue = OnceScattered::u_edges();
  double sum = 0;
  for (std::size_t i = 0; i + 1 < se.size(); ++i)
    sum += gauss8(
        [&](double s) {
          double inner = 0;
          for (std::size_t j = 0; j + 1 < ue.size(); ++j)
            inner += gauss8(
                [&](double u) { return std::exp(-tau * (s + exit_distance_from_axis(s, sample_hg(hg, u).cos_theta))); },
                ue[j], ue[j + 1]);
          return tau * inner;
        },
        se[i], se[i + 1]);
  return sum;
}

OnceScattered::OnceScattered(double tau, double g)
    : tau_(tau), hg_(HgParams<double>::make(g)), s_edges_(s_edges()), u_edges_(u_edges()) {
  // L is concave in s (t is: a line plus the root of a concave quadratic) and falls as mu
  // grows, so on a cell its least value is at the cell's largest mu and one of its two s
  // edges. Weights are taken relative to e^{-tau}, as L >= 1: no underflow before tau ~ 700
  // cells away from the forward direction.
  std::vector<double> weight;
  for (int i = 0; i < kSCells; ++i)
    for (int j = 0; j < kUCells; ++j) {
      const double mu_hi = mu(u_edges_[j + 1]);
      const double l = std::min(path_length(s_edges_[i], mu_hi), path_length(s_edges_[i + 1], mu_hi));
      min_length_.push_back(l);
      weight.push_back((s_edges_[i + 1] - s_edges_[i]) * (u_edges_[j + 1] - u_edges_[j]) * std::exp(-tau * (l - 1)));
      bound_mass_ += weight.back();
    }
  cells_ = AliasTable(weight);
}

double OnceScattered::acceptance() const {
  // The bound's mass is tau e^{-tau} bound_mass_ (the weights are relative to e^{-tau}).
  const double p = once_scattered_probability(tau_, hg_.g);
  return bound_mass_ > 0 && p > 0 ? std::min(1.0, p / (tau_ * std::exp(-tau_)) / bound_mass_) : 1;
}

bool OnceScattered::try_draw(double v0, double v2, double v3, double& s, double& mu_out, double& sin_theta) const {
  double in_cell;
  const int cell = cells_.sample(v0, in_cell);
  const int i = cell / kUCells, j = cell % kUCells;
  s = s_edges_[i] + in_cell * (s_edges_[i + 1] - s_edges_[i]);
  const double u = u_edges_[j] + v2 * (u_edges_[j + 1] - u_edges_[j]);
  const CosSin<double> cs = sample_hg(hg_, u);
  mu_out = cs.cos_theta, sin_theta = cs.sin_theta;
  return v3 < std::exp(-tau_ * (path_length(s, mu_out) - min_length_[std::size_t(cell)]));
}

void OnceScattered::sample(double u0, double u1, double u2, double u3, Vec3& point, Vec3& direction) const {
  double s, mu, sin_theta;
  if (!try_draw(u0, u2, u3, s, mu, sin_theta)) {
    RetryStream retry(u0, u1, u2, u3);
    while (!try_draw(retry.uniform(), retry.uniform(), retry.uniform(), s, mu, sin_theta)) {
    }
  }
  double sp, cp;
  sincos_2pi(u1, sp, cp);
  direction = {sin_theta * cp, sin_theta * sp, mu};
  const double t = exit_distance_from_axis(s, mu);
  point = normalize({t * direction.x, t * direction.y, s + t * mu});
}

}  // namespace stf
