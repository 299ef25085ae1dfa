// Fitting to a tolerance: coarsening, the certificate's statistics, and the whole choice
// against a large reference.
#include "tolerance.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "evaluate.h"
#include "grid.h"
#include "precompute.h"

namespace stf::fit {
namespace {

Table make_table(double tau, double albedo, double g, std::int64_t paths, std::int64_t seed,
                 const char* grid = "healpix:8", int bins = 36) {
  PrecomputeSettings s;
  s.paths = paths;
  s.grid = grid;
  s.alpha_bins = bins;
  s.seed = seed;
  return *precompute({albedo * tau, (1 - albedo) * tau, g, 1}, s);
}

// A one-lobe model per alpha bin whose lobe tilts and sharpens with alpha: its exit
// distribution varies smoothly across bins and cells.
StfModel lobe_model(const Table& t, double kappa_scale, double tilt) {
  StfModel m;
  m.kind = ModelKind::kVmf;
  m.lobes = 1;
  m.alpha_edges = t.alpha_edges;
  double total = 0;
  for (int b = 0; b < t.alpha_bins; ++b) {
    const double alpha = 0.5 * (t.alpha_edges[b] + t.alpha_edges[b + 1]), theta = tilt * alpha;
    m.alpha_probability.push_back(std::cos(t.alpha_edges[b]) - std::cos(t.alpha_edges[b + 1]) + 0.02);
    total += m.alpha_probability.back();
    m.status.push_back(BinStatus::kFitted);
    m.vmf.push_back({1, kappa_scale * (1 + 3 * alpha), {std::sin(theta), 0, std::cos(theta)}});
  }
  for (double& p : m.alpha_probability) p /= total;
  return m;
}

// The model's joint (alpha bin, cell) distribution on the table's grid.
std::vector<double> joint(const StfModel& m, const Table& t) {
  auto grid = make_grid(t.grid);
  const QuadratureLevels levels(*grid);
  std::vector<double> p;
  for (int b = 0; b < m.bins(); ++b)
    for (double q : model_cell_probabilities(m, b, levels)) p.push_back(m.alpha_probability[b] * q);
  return p;
}

// A table with `n` escapes drawn from `p` (multinomial, by sequential binomials), each
// escape in either half with probability 1/2.
Table sampled(Table t, const std::vector<double>& p, std::int64_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  t.weight_half = {std::vector<double>(p.size(), 0.0), std::vector<double>(p.size(), 0.0)};
  double rest = 1;
  for (std::size_t i = 0; i < p.size() && n > 0; ++i) {
    std::binomial_distribution<std::int64_t> draw(n, std::clamp(p[i] / rest, 0.0, 1.0));
    const std::int64_t k = draw(rng);
    n -= k;
    rest -= p[i];
    t.weight_half[0][i] = double(std::binomial_distribution<std::int64_t>(k, 0.5)(rng));
    t.weight_half[1][i] = double(k) - t.weight_half[0][i];
  }
  return t;
}

std::vector<double> distribution(const Table& t) {
  std::vector<double> y = t.weight();
  double total = 0;
  for (double v : y) total += v;
  for (double& v : y) v /= total;
  return y;
}

TEST(Coarsen, ParentsHoldTheirChildrenAndSumsArePreserved) {
  for (const char* spec : {"healpix:8", "csc:8"}) {
    Table t = make_table(4, 0.99, 0.7, 20000, 1, spec, 36);
    auto fine = make_grid(spec);
    for (int levels : {1, 2}) {
      auto coarse = make_grid(fine->coarser(levels));
      std::vector<std::int64_t> parent = fine->parents(levels);
      std::vector<int> children(coarse->cell_count(), 0);
      for (std::int64_t c = 0; c < fine->cell_count(); ++c) {
        ++children[parent[c]];
        EXPECT_EQ(coarse->cell(fine->centre(c)), parent[c]) << spec << " cell " << c;
      }
      for (int k : children) EXPECT_EQ(k, 1 << (2 * levels)) << spec;
      Table c = coarsen_table(t, 3, levels);
      EXPECT_EQ(c.alpha_bins, 12);
      EXPECT_EQ(c.cells, coarse->cell_count());
      EXPECT_EQ(c.alpha_edges.back(), t.alpha_edges.back());
      double fine_sum = 0, coarse_sum = 0, omega = 0;
      for (double w : t.weight()) fine_sum += w;
      for (double w : c.weight()) coarse_sum += w;
      for (double s : c.solid_angle) omega += s;
      EXPECT_EQ(fine_sum, coarse_sum);
      EXPECT_NEAR(omega, 4 * kPi, 1e-9);
    }
  }
  EXPECT_EQ(make_grid("csc:45")->coarser(1), "");
}

// The coarsening estimate against the same Cauchy-Schwarz bound computed from the true
// distribution (with the same weights, from the other table): with 2e6 escapes per table its
// noise (sd about sqrt(2 * 10368) / 1e6 in chi^2) moves the result by under 0.003.
TEST(Coarsen, ErrorEstimateMatchesTheTruth) {
  Table t = make_table(4, 0.99, 0.7, 2000, 1);
  const StfModel truth = lobe_model(t, 2, 0.5);
  const std::vector<double> p = joint(truth, t);
  const Table a = sampled(t, p, 2'000'000, 11), b = sampled(t, p, 2'000'000, 12);
  const std::vector<double> yo = distribution(b);
  for (int f : {2, 6, 36}) {
    // p against p spread over groups of f bins by area; weights as coarsening_tv's.
    double chi2 = 0, weights = 0;
    for (int j = 0; j < t.alpha_bins / f; ++j) {
      auto area = [&](int lo, int hi) { return std::cos(t.alpha_edges[lo]) - std::cos(t.alpha_edges[hi]); };
      for (std::int64_t c = 0; c < t.cells; ++c) {
        double group = 0, other = 0;
        for (int a2 = j * f; a2 < (j + 1) * f; ++a2) {
          group += p[std::size_t(a2) * t.cells + c];
          other += yo[std::size_t(a2) * t.cells + c];
        }
        for (int a2 = j * f; a2 < (j + 1) * f; ++a2) {
          const std::size_t i = std::size_t(a2) * t.cells + c;
          const double share = area(a2, a2 + 1) / area(j * f, (j + 1) * f), e = p[i] - share * group;
          const double w = std::max(share * other, yo[i]);
          weights += w;
          if (w > 0) chi2 += e * e / w;
        }
      }
    }
    EXPECT_NEAR(coarsening_tv(a, b, f, 0), 0.5 * std::sqrt(chi2 * weights), 0.003) << "factor " << f;
  }
  // Nothing varies within the grid's cells at healpix:8 -> 4 beyond what the lobes do:
  // the grid estimate is positive and well below the coarsest alpha grouping's.
  EXPECT_LT(coarsening_tv(a, b, 1, 1), coarsening_tv(a, b, 36, 0));
}

// The chi^2 estimate is unbiased for sum (p - m)^2 / w and the bound covers the true TV:
// over 40 held-out tables of 2e4 escapes, the mean lies within 4 standard errors of the
// exact value and the bound falls below the true TV in at most 5 (expected: about 1).
TEST(Certify, UnbiasedAndCoversTheTrueDistance) {
  Table t = make_table(4, 0.99, 0.7, 2000, 1);
  const StfModel truth = lobe_model(t, 2, 0.5), model = lobe_model(t, 2.6, 0.45);
  const std::vector<double> p = joint(truth, t), m = joint(model, t);
  const Table fit = sampled(t, p, 200'000, 3);
  const std::vector<double> tf = [&] {
    std::vector<double> v = fit.weight_half[0];
    for (double& x : v) x /= 2e5;
    return v;
  }();
  double exact_chi2 = 0, exact_tv = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double w = std::max(m[i], tf[i]);
    if (w > 0) exact_chi2 += (p[i] - m[i]) * (p[i] - m[i]) / w;
    exact_tv += 0.5 * std::abs(p[i] - m[i]);
  }
  const int replicas = 40;
  double mean = 0, sd = 0;
  int uncovered = 0;
  for (int r = 0; r < replicas; ++r) {
    Certificate c = certify(model, fit, sampled(t, p, 20'000, 100 + r));
    mean += c.chi2 / replicas;
    sd += c.chi2_sd / replicas;
    uncovered += c.tv_bound < exact_tv;
    ASSERT_TRUE(std::isfinite(c.tv_bound));
  }
  EXPECT_NEAR(mean, exact_chi2, 4 * sd / std::sqrt(double(replicas)));
  EXPECT_LE(uncovered, 5);
  // The model itself as the truth: the estimate is zero within noise.
  Certificate self = certify(truth, fit, sampled(t, p, 20'000, 99));
  EXPECT_LT(std::abs(self.chi2), 4 * self.chi2_sd);
}

// The whole choice on real walks: the looser tolerance never needs more alpha bins, cells or
// bytes, and each certified bound lies above the TV measured against a 2e7-path reference
// (whose own noise, about 0.01, only raises the measured value).
TEST(FitToTolerance, ChoosesLessForLooserTolerancesAndTheBoundHolds) {
  const Table fit = make_table(4, 0.99, 0.7, 400'000, 1), heldout = make_table(4, 0.99, 0.7, 400'000, 2);
  const Table reference = make_table(4, 0.99, 0.7, 20'000'000, 3);
  FitSettings s = parse_model_spec("vmf:auto");
  ToleranceFit loose = fit_to_tolerance(fit, heldout, 0.3, s), tight = fit_to_tolerance(fit, heldout, 0.12, s);
  ASSERT_TRUE(loose.met);
  ASSERT_TRUE(tight.met);
  EXPECT_LE(loose.fitted.alpha_bins, tight.fitted.alpha_bins);
  EXPECT_LE(loose.fitted.cells, tight.fitted.cells);
  EXPECT_LE(loose.model.packed_bytes(), tight.model.packed_bytes());
  for (const ToleranceFit* r : {&loose, &tight}) {
    Evaluation ev = evaluate(r->model, reference);
    EXPECT_LE(ev.joint_tv, r->certificate.tv_bound) << r->fitted.alpha_bins << " bins, " << r->fitted.grid;
  }
  EXPECT_LT(loose.fitted.alpha_bins, fit.alpha_bins);  // smooth in alpha: a loose tolerance merges bins
}

}  // namespace
}  // namespace stf::fit
