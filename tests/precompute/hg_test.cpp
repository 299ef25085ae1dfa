#include "stf/hg.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <vector>

#include "chi2.h"
#include "stf/core/rng.h"
#include "seed.h"

namespace stf {
namespace {

const double kGs[] = {-0.999, -0.5, 0.0, -1e-7, 1e-7, 0.3, 0.9, 0.999};

// Adaptive Simpson: the HG peak at |g| -> 1 is ~1e-6 wide in mu, so fixed rules miss it.
double integrate(const std::function<double(double)>& f, double a, double b, double tol, int depth,
                 double fa, double fm, double fb) {
  double m = 0.5 * (a + b), lm = 0.5 * (a + m), rm = 0.5 * (m + b);
  double flm = f(lm), frm = f(rm);
  double whole = (b - a) / 6 * (fa + 4 * fm + fb);
  double left = (m - a) / 6 * (fa + 4 * flm + fm), right = (b - m) / 6 * (fm + 4 * frm + fb);
  if (depth <= 0 || std::abs(left + right - whole) <= 15 * tol)
    return left + right + (left + right - whole) / 15;
  return integrate(f, a, m, tol / 2, depth - 1, fa, flm, fm) +
         integrate(f, m, b, tol / 2, depth - 1, fm, frm, fb);
}

double integrate(const std::function<double(double)>& f, double a, double b, double tol = 1e-12) {
  return integrate(f, a, b, tol, 60, f(a), f(0.5 * (a + b)), f(b));
}

// The sampled angle's distance from the lobe's peak, d = 1 - mu for g >= 0 and 1 + mu for
// g < 0, taken from (cos, sin) without cancellation: float cannot resolve mu near +-1, but
// the angle, which is what the walk uses, stays accurate through sin(theta).
template <typename T>
double distance_from_peak(double g, CosSin<T> cs) {
  double c = double(cs.cos_theta), s2 = double(cs.sin_theta) * double(cs.sin_theta);
  if (g < 0) c = -c;
  return c > 0 ? s2 / (1 + c) : 1 - c;
}

// Bin edges in d spreading HG's mass: uniform in ln(1 + g^2 - 2 |g| (1 - d)), the variable in
// which the density is a power law; uniform in d when |g| is tiny.
std::vector<double> peak_distance_edges(double g, int bins) {
  const double a = std::abs(g);
  std::vector<double> edges(bins + 1);
  for (int i = 0; i <= bins; ++i) {
    double t = double(i) / bins;
    if (a < 1e-3) {
      edges[i] = 2 * t;
    } else {
      double lo = std::log((1 - a) * (1 - a)), hi = std::log((1 + a) * (1 + a));
      edges[i] = (std::exp(lo + (hi - lo) * t) - (1 - a) * (1 - a)) / (2 * a);
    }
  }
  edges.front() = 0;
  edges.back() = 2;
  return edges;
}

template <typename T>
void check_hg_chi2(double g, std::uint64_t seed) {
  SCOPED_TRACE(test::seed_trace(seed));
  const int bins = 60, n = 1'000'000;
  std::vector<double> edges = peak_distance_edges(g, bins);
  std::vector<double> observed(bins, 0), expected(bins);
  const double a = std::abs(g);  // d for g < 0 is distributed as 1 - mu for |g|
  for (int b = 0; b < bins; ++b)
    expected[b] = n * integrate([a](double d) { return hg_pdf_mu(a, 1 - d); }, edges[b], edges[b + 1]);
  std::uint64_t state = seed;
  HgParams<T> params = HgParams<T>::make(g);
  for (int i = 0; i < n; ++i) {
    T xi = T(double(splitmix64(state) >> 11) * 0x1p-53);
    double d = distance_from_peak(g, sample_hg(params, xi));
    int b = int(std::upper_bound(edges.begin() + 1, edges.end() - 1, d) - edges.begin()) - 1;
    observed[b] += 1;
  }
  test::Chi2Result r = test::chi2_test(observed, expected);
  EXPECT_GT(r.p_value, test::kChi2Alpha) << "g = " << g << ": " << r.describe();
}

TEST(HenyeyGreenstein, SamplesMatchPdfChiSquareDouble) {
  for (double g : kGs) check_hg_chi2<double>(g, test::test_seed(11));
}

TEST(HenyeyGreenstein, SamplesMatchPdfChiSquareFloat) {
  for (double g : kGs) check_hg_chi2<float>(g, test::test_seed(12));
}

TEST(HenyeyGreenstein, PdfIntegratesToOne) {
  for (double g : kGs) {
    double total = integrate([g](double mu) { return hg_pdf_mu(g, mu); }, -1, 1, 1e-13);
    EXPECT_NEAR(total, 1.0, 1e-9) << "g = " << g;
  }
}

TEST(HenyeyGreenstein, MeanCosineEqualsG) {
  const std::uint64_t seed = test::test_seed(13);
  SCOPED_TRACE(test::seed_trace(seed));
  const int n = 2'000'000;
  for (double g : kGs) {
    HgParams<double> params = HgParams<double>::make(g);
    std::uint64_t state = seed;
    double sum = 0;
    for (int i = 0; i < n; ++i) sum += sample_hg(params, double(splitmix64(state) >> 11) * 0x1p-53).cos_theta;
    // Var(mu) <= 1 - g^2 bounds the standard error; 6 sigma.
    EXPECT_NEAR(sum / n, g, 6 * std::sqrt((1 - g * g) / n)) << "g = " << g;
  }
}

TEST(HenyeyGreenstein, FiniteAndInRangeAtExtremes) {
  const double gs[] = {-0.999999, -0.999, -1e-300, 0.0, 1e-300, 1e-8, 0.999, 0.999999};
  const double xis[] = {0.0, std::numeric_limits<double>::min(), 1e-12, 0.5, 1 - 1e-12,
                        1 - std::numeric_limits<double>::epsilon() / 2, 1.0};
  for (double g : gs) {
    for (double xi : xis) {
      CosSin<double> d = sample_hg(HgParams<double>::make(g), xi);
      CosSin<float> f = sample_hg(HgParams<float>::make(g), float(xi));
      for (double v : {d.cos_theta, d.sin_theta, double(f.cos_theta), double(f.sin_theta)}) {
        ASSERT_TRUE(std::isfinite(v)) << "g = " << g << ", xi = " << xi;
        EXPECT_LE(std::abs(v), 1.0) << "g = " << g << ", xi = " << xi;
      }
      EXPECT_NEAR(d.cos_theta * d.cos_theta + d.sin_theta * d.sin_theta, 1.0, 1e-12);
    }
    EXPECT_EQ(sample_hg(HgParams<double>::make(g), 0.0).cos_theta, -1.0) << g;
    EXPECT_EQ(sample_hg(HgParams<double>::make(g), 1.0).cos_theta, 1.0) << g;
  }
}

TEST(HenyeyGreenstein, IsotropicAtZeroAndTinyG) {
  // At g = 0 the inversion is exactly mu = 2 xi - 1; at |g| = 1e-7 within O(g).
  for (double xi : {0.1, 0.25, 0.5, 0.8}) {
    EXPECT_DOUBLE_EQ(sample_hg(HgParams<double>::make(0.0), xi).cos_theta, 2 * xi - 1);
    EXPECT_NEAR(sample_hg(HgParams<double>::make(1e-7), xi).cos_theta, 2 * xi - 1, 1e-6);
  }
}

}  // namespace
}  // namespace stf
