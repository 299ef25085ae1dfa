// One chi-square goodness-of-fit utility for every sampler and estimator test: observed
// counts against expected counts, bins with small expectation pooled, p-value from the
// regularised incomplete gamma function.
#pragma once

#include <string>
#include <vector>

namespace stf::test {

struct Chi2Result {
  double statistic = 0;
  int dof = 0;
  double p_value = 1;
  std::string describe() const;
};

// Pools adjacent bins until each pooled expectation is at least `min_expected`, then tests.
// `expected` must sum to the same total as `observed` (a multinomial test, dof = bins - 1).
// An observed count in a bin with zero expectation gives p = 0.
Chi2Result chi2_test(const std::vector<double>& observed, const std::vector<double>& expected,
                     double min_expected = 5);

// Two-sample (homogeneity) test of two histograms over the same bins.
Chi2Result chi2_two_sample(const std::vector<double>& a, const std::vector<double>& b,
                           double min_expected = 5);

// Q(a, x) = Gamma(a, x) / Gamma(a): the chi-square upper tail is Q(dof / 2, statistic / 2).
double gamma_q(double a, double x);

// Significance used by the suite: a correct implementation fails one test in 1e6 runs.
inline constexpr double kChi2Alpha = 1e-6;

}  // namespace stf::test
