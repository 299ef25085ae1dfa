#include "chi2.h"

#include <cmath>
#include <cstdio>

namespace stf::test {

std::string Chi2Result::describe() const {
  char buf[128];
  std::snprintf(buf, sizeof buf, "chi2 = %.2f, dof = %d, p = %.3g", statistic, dof, p_value);
  return buf;
}

double gamma_q(double a, double x) {
  if (x <= 0) return 1;
  double log_prefix = a * std::log(x) - x - std::lgamma(a);
  if (x < a + 1) {  // series for P(a, x)
    double term = 1 / a, sum = term;
    for (int n = 1; n < 10000 && std::abs(term) > 1e-16 * std::abs(sum); ++n) {
      term *= x / (a + n);
      sum += term;
    }
    return 1 - sum * std::exp(log_prefix);
  }
  // Continued fraction for Q(a, x) (modified Lentz).
  const double tiny = 1e-300;
  double b = x + 1 - a, c = 1 / tiny, d = 1 / b, h = d;
  for (int i = 1; i < 10000; ++i) {
    double an = -i * (i - a);
    b += 2;
    d = an * d + b;
    if (std::abs(d) < tiny) d = tiny;
    c = b + an / c;
    if (std::abs(c) < tiny) c = tiny;
    d = 1 / d;
    double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1) < 1e-16) break;
  }
  return std::exp(log_prefix) * h;
}

namespace {

// Adjacent pooling so that every pooled bin has expectation >= min_expected.
void pool(const std::vector<double>& obs, const std::vector<double>& exp, double min_expected,
          std::vector<double>& pooled_obs, std::vector<double>& pooled_exp) {
  double o = 0, e = 0;
  for (std::size_t i = 0; i < obs.size(); ++i) {
    o += obs[i];
    e += exp[i];
    if (e >= min_expected) {
      pooled_obs.push_back(o);
      pooled_exp.push_back(e);
      o = e = 0;
    }
  }
  if (e > 0 || o > 0) {
    if (pooled_exp.empty()) {
      pooled_obs.push_back(o);
      pooled_exp.push_back(e);
    } else {
      pooled_obs.back() += o;
      pooled_exp.back() += e;
    }
  }
}

}  // namespace

Chi2Result chi2_test(const std::vector<double>& observed, const std::vector<double>& expected,
                     double min_expected) {
  std::vector<double> o, e;
  pool(observed, expected, min_expected, o, e);
  Chi2Result r;
  for (std::size_t i = 0; i < o.size(); ++i) {
    if (e[i] <= 0) {
      if (o[i] > 0) r.p_value = 0;
      continue;
    }
    r.statistic += (o[i] - e[i]) * (o[i] - e[i]) / e[i];
    ++r.dof;
  }
  r.dof = std::max(r.dof - 1, 1);
  if (r.p_value != 0) r.p_value = gamma_q(0.5 * r.dof, 0.5 * r.statistic);
  return r;
}

Chi2Result chi2_two_sample(const std::vector<double>& a, const std::vector<double>& b,
                           double min_expected) {
  double na = 0, nb = 0;
  for (double v : a) na += v;
  for (double v : b) nb += v;
  // Pool on the combined histogram, then compare each pooled bin's split.
  std::vector<double> sum(a.size()), pa, pb, ps, unused;
  for (std::size_t i = 0; i < a.size(); ++i) sum[i] = a[i] + b[i];
  pool(a, sum, min_expected, pa, ps);
  pool(b, sum, min_expected, pb, unused);
  Chi2Result r;
  for (std::size_t i = 0; i < ps.size(); ++i) {
    double ea = ps[i] * na / (na + nb), eb = ps[i] * nb / (na + nb);
    r.statistic += (pa[i] - ea) * (pa[i] - ea) / ea + (pb[i] - eb) * (pb[i] - eb) / eb;
  }
  r.dof = std::max(int(ps.size()) - 1, 1);
  r.p_value = gamma_q(0.5 * r.dof, 0.5 * r.statistic);
  return r;
}

}  // namespace stf::test
