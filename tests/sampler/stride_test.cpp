// The stride form against the model's pdf (chi-square), part by part and together, and its
// kernels against libm.
#include "stf/stride.h"

#include <gtest/gtest.h>

#include <cmath>

#include "chi2.h"
#include "seed.h"
#include "stf/sampler.h"
#include "test_models.h"
#include "test_numerics.h"

namespace stf {

namespace {

using test::integrate;
using test::Uniforms;

// Exit histograms: alpha bin x thirds of its area x quarters of the azimuth beta x the local
// direction's cell (beta turned back) on an equal-area grid of nz x 2 nz cells; then one bin
// for the uncollided delta and one for the once-scattered part.
struct ExitBins {
  const StfModel& model;
  static constexpr int kThirds = 3, kQuarters = 4, kNz = 6;
  int cells() const { return 2 * kNz * kNz; }
  int size() const { return model.bins() * kThirds * kQuarters * cells() + 2; }
  int bin(const Stride& s) const {
    if (s.component != kSmooth) return size() - (s.component == kUncollided ? 2 : 1);
    const int bins = model.bins();
    const double alpha = std::atan2(std::hypot(s.point.x, s.point.y), s.point.z);
    const int b = std::min(bins - 1, int(alpha / kPi * bins));
    const double c0 = std::cos(model.alpha_edges[b]), c1 = std::cos(model.alpha_edges[b + 1]);
    const int k = std::clamp(int((c0 - s.point.z) / (c0 - c1) * kThirds), 0, kThirds - 1);
    double beta = std::atan2(s.point.y, s.point.x);
    beta = beta < 0 ? beta + 2 * kPi : beta;
    const int q = std::min(kQuarters - 1, int(beta / (2 * kPi) * kQuarters));
    const double cb = std::cos(beta), sb = std::sin(beta);
    const Vec3 local{cb * s.direction.x + sb * s.direction.y, -sb * s.direction.x + cb * s.direction.y, s.direction.z};
    return ((b * kThirds + k) * kQuarters + q) * cells() + equal_area_cell(kNz, local);
  }
  // Expected probabilities from ShellSampler::pdf (the smooth part's density times its share,
  // per unit area per steradian), integrated over each bin; the parts' own probabilities.
  std::vector<double> expected(const ShellSampler& s) const {
    std::vector<double> e(std::size_t(size()), 0.0);
    for (int b = 0; b < model.bins(); ++b)
      for (int k = 0; k < kThirds; ++k) {
        const std::vector<double> third = expected_third(s, b, k);
        for (int q = 0; q < kQuarters; ++q)
          for (int c = 0; c < cells(); ++c) e[std::size_t(((b * kThirds + k) * kQuarters + q) * cells() + c)] = third[c];
      }
    e[e.size() - 2] = model.uncollided_probability();
    e[e.size() - 1] = model.once_fraction;
    return e;
  }
  // One quarter of beta of the third k of bin b, per direction cell.
  std::vector<double> expected_third(const ShellSampler& s, int b, int k) const {
    const double c0 = std::cos(model.alpha_edges[b]), c1 = std::cos(model.alpha_edges[b + 1]);
    std::vector<double> out(std::size_t(cells()), 0.0);
    for (int c = 0; c < cells(); ++c) {
      const int row = c / (2 * kNz), col = c % (2 * kNz);
      const double z0 = -1 + 2.0 * row / kNz, z1 = z0 + 2.0 / kNz, p0 = kPi * col / kNz, p1 = p0 + kPi / kNz;
      const auto at_u = [&](double u) {
        const double z = c0 + u * (c1 - c0), r = std::sqrt(std::max(0.0, 1 - z * z));
        return integrate([&](double wz) {
          const double wr = std::sqrt(std::max(0.0, 1 - wz * wz));
          return integrate([&](double phi) { return s.pdf({r, 0, z}, {wr * std::cos(phi), wr * std::sin(phi), wz}); }, p0, p1, 2);
        }, z0, z1, 2);
      };
      // Split at the bin's middle, where blend hats have their kinks.
      const double v0 = double(k) / kThirds, v1 = double(k + 1) / kThirds;
      double sum = 0;
      for (auto [a, z] : {std::pair{v0, std::min(v1, 0.5)}, std::pair{std::max(v0, 0.5), v1}})
        if (z > a) sum += integrate(at_u, a, z, 1);
      out[std::size_t(c)] = sum * 2 * kPi * (c0 - c1) / kQuarters;
    }
    return out;
  }
};

// A model of `bins` alpha bins whose tilts cycle through `tilts`.
StfModel with_bins(int bins, const std::vector<double>& tilts) {
  StfModel m = test::make_vmf_model();
  const StfModel base = m;
  m.alpha_edges.clear(), m.alpha_probability.clear(), m.status.clear(), m.vmf.clear(), m.alpha_tilt.clear();
  for (int b = 0; b <= bins; ++b) m.alpha_edges.push_back(kPi * b / bins);
  for (int b = 0; b < bins; ++b) {
    m.alpha_probability.push_back(1.0 / bins), m.status.push_back(BinStatus::kFitted);
    m.alpha_tilt.push_back(tilts[std::size_t(b) % tilts.size()]);
    const auto lobes = base.lobes_of(b % base.bins());
    m.vmf.insert(m.vmf.end(), lobes.begin(), lobes.end());
  }
  return m;
}

StfModel with_once_scattered(StfModel m) {
  m.once_fraction = 0.15;
  return m;
}

TEST(Stride, DrawsTheModelsDistributionChiSquare) {
  const std::uint64_t seed = test::test_seed(81);
  SCOPED_TRACE(test::seed_trace(seed));
  using namespace test;
  for (const StfModel& model :
       {make_vmf_model(), make_sh_model(), hemispherical(with_uncollided(make_vmf_model())), turned(tilted(make_vmf_model())),
        blended(turned(tilted(hemispherical(make_vmf_model()))), 2), blended_by_bin(turned(tilted(make_vmf_model()))),
        turned(blended(tilted(make_sh_model()))),
        with_once_scattered(with_uncollided(turned(tilted(hemispherical(make_vmf_model()))))),
        turned(hemispherical(with_bins(12, {0.0, 0.3, 0.0, -0.1}))), lifted(with_uncollided(make_vmf_model())),
        blended(turned(tilted(lifted(make_vmf_model()))), 2), turned(lifted(with_bins(12, {0.0, 0.3, 0.0, -0.1})))}) {
    const ShellSampler sampler(model);
    const StrideForm form(model);
    if (model.bins() == 12) {
      EXPECT_GE(form.polynomial_bins(), 4);  // exit angles through polynomials too
    }
    const ExitBins bins{sampler.model()};
    const int n = 400000;
    std::vector<double> observed(std::size_t(bins.size()), 0.0), expected = bins.expected(sampler);
    for (double& e : expected) e *= n;
    Uniforms u{seed};
    for (int i = 0; i < n; ++i) observed[std::size_t(bins.bin(form.local(u)))] += 1;
    const Chi2Result r = chi2_test(observed, expected);
    EXPECT_GT(r.p_value, kChi2Alpha) << r.describe() << " tilt " << !model.alpha_tilt.empty() << " blend "
                                     << model.alpha_blend << " turn " << !model.alpha_turn.empty() << " hemispherical "
                                     << model.hemispherical << " lifted " << model.lifted << " sh " << (model.kind == ModelKind::kSh);
  }
}

// ShellSampler::jump from four uniforms (the rest from a stream seeded by them) draws the same.
TEST(Stride, SamplerJumpDrawsTheModelsDistributionChiSquare) {
  const StfModel model = with_once_scattered(test::with_uncollided(test::turned(test::hemispherical(with_bins(12, {0.0, 0.3})))));
  const ShellSampler sampler(model);
  const ExitBins bins{sampler.model()};
  const int n = 400000;
  std::vector<double> observed(std::size_t(bins.size()), 0.0), expected = bins.expected(sampler);
  for (double& e : expected) e *= n;
  Uniforms u{86};
  for (int i = 0; i < n; ++i) {
    const double u0 = u(), u1 = u(), u2 = u(), u3 = u();
    const WorldExit e = sampler.jump({0, 0, 0}, {0, 0, 1}, 1.0, u0, u1, u2, u3);
    observed[std::size_t(bins.bin({e.point, e.direction, e.component}))] += 1;
  }
  const test::Chi2Result r = test::chi2_test(observed, expected);
  EXPECT_GT(r.p_value, test::kChi2Alpha) << r.describe();
}

// ShellSampler::sample of lifted lobes (whose direction density changes with the exit angle
// inside a bin, as FullSampleMatchesPdfChiSquare's bin-level density does not) against the pdf.
TEST(Stride, SamplerSampleOfLiftedLobesDrawsThePdfChiSquare) {
  const std::uint64_t seed = test::test_seed(87);
  SCOPED_TRACE(test::seed_trace(seed));
  for (const StfModel& model : {test::lifted(test::with_uncollided(test::make_vmf_model())),
                               test::blended(test::turned(test::tilted(test::lifted(test::make_vmf_model()))), 2)}) {
    const ShellSampler sampler(model);
    const ExitBins bins{sampler.model()};
    const int n = 400000;
    std::vector<double> observed(std::size_t(bins.size()), 0.0), expected = bins.expected(sampler);
    for (double& e : expected) e *= n;
    Uniforms u{seed};
    for (int i = 0; i < n; ++i) {
      const double u0 = u(), u1 = u(), u2 = u(), u3 = u();
      const ExitSample e = sampler.sample(u0, u1, u2, u3);
      observed[std::size_t(bins.bin({e.point, e.direction, e.component}))] += 1;
    }
    const test::Chi2Result r = test::chi2_test(observed, expected);
    EXPECT_GT(r.p_value, test::kChi2Alpha) << r.describe() << " turn " << !model.alpha_turn.empty();
  }
}

// The once-scattered part alone: its exit points and directions as ShellSampler draws them.
TEST(Stride, OnceScatteredPartIsTheSamplersChiSquare) {
  const StfModel model = with_once_scattered(test::make_vmf_model());
  const ShellSampler sampler(model);
  const StrideForm form(model);
  const int rows = 12, n = 300000;
  const auto cell = [&](const Vec3& p, const Vec3& d) {
    return std::min(rows - 1, int((1 - p.z) / 2 * rows)) * rows + std::min(rows - 1, int((1 - d.z) / 2 * rows));
  };
  std::vector<double> a(rows * rows, 0.0), b(rows * rows, 0.0);
  Uniforms u{82}, v{83};
  for (int drawn = 0; drawn < n;) {
    const Stride s = form.local(u);
    if (s.component == kOnceScattered) a[std::size_t(cell(s.point, s.direction))] += 1, ++drawn;
  }
  for (int drawn = 0; drawn < n;) {
    const ExitSample s = sampler.sample(v(), v(), v(), v());
    if (s.component == kOnceScattered) b[std::size_t(cell(s.point, s.direction))] += 1, ++drawn;
  }
  const test::Chi2Result r = test::chi2_two_sample(a, b);
  EXPECT_GT(r.p_value, test::kChi2Alpha) << r.describe();
}

// jump() is the local draw carried into the frame of the path's heading, at its radius.
TEST(Stride, JumpIsTheLocalDrawInThePathsFrame) {
  const StfModel model = test::turned(test::hemispherical(test::with_uncollided(test::make_vmf_model())));
  const StrideForm form(model);
  Uniforms u{84};
  for (int i = 0; i < 20000; ++i) {
    const Vec3 start{u(), u(), u()}, heading = sample_vmf({1, 0, {0, 0, 1}}, u(), u());
    const double radius = 0.5 + u();
    Uniforms a = u, b = u;
    const Stride local = form.local(a), world = form.jump(start, heading, radius, b);
    Vec3 x, y;
    orthonormal_basis(heading, x, y);
    const Vec3 d{(world.point.x - start.x) / radius, (world.point.y - start.y) / radius, (world.point.z - start.z) / radius};
    ASSERT_EQ(world.component, local.component);
    ASSERT_NEAR(dot(d, heading), local.point.z, 1e-12);
    ASSERT_NEAR(dot(d, x), local.point.x, 1e-12);
    ASSERT_NEAR(dot(world.direction, heading), local.direction.z, 1e-12);
    ASSERT_NEAR(dot(world.direction, y), local.direction.y, 1e-12);
    ASSERT_NEAR(length(local.point), 1, 1e-13);
    ASSERT_NEAR(length(local.direction), 1, 1e-13);
    u = b;
  }
}

// Uniforms at the ends of [0, 1), cycled from every phase: exits stay finite and unit.
TEST(Stride, ExtremeUniformsStayFinite) {
  const double ends[] = {0.0, 1e-300, 0.5, std::nextafter(1.0, 0.0)};
  using namespace test;
  for (const StfModel& model : {make_vmf_model(), make_sh_model(), with_once_scattered(with_uncollided(
                                    blended(turned(tilted(hemispherical(make_vmf_model()))), 2)))}) {
    const StrideForm form(model);
    for (int start = 0; start < 256; ++start) {
      int k = start;
      const auto uniform = [&] { return ends[(k = (k * 5 + 3) & 1023) & 3]; };  // low bits: period 4
      const Stride s = form.local(uniform);
      ASSERT_NEAR(length(s.point), 1, 1e-12) << start;
      ASSERT_NEAR(length(s.direction), 1, 1e-12) << start;
    }
  }
}

// Where a bin draws its exit angle through the polynomial, it is within kAngleError of the
// tilt's exact quantile: tilts from flat to the largest a fit keeps, bins of 4 to 30 degrees.
// Bins of moderate tilt (those of dense media's models are below 0.7) have their polynomial.
TEST(Stride, ExitAnglePolynomialsMeetTheirBound) {
  const std::vector<double> tilts = {-40, -4, -0.5, 0, 0.3, 1e-9, 5, 40};
  for (const int bins : {6, 12, 45}) {
    const StfModel model = with_bins(bins, tilts);
    const StrideForm form(model);
    int moderate = 0;  // bins of |tilt| <= 0.3 three or more from the poles: each has its polynomial
    for (int b = 3; b + 3 < bins; ++b) moderate += std::abs(model.alpha_tilt[std::size_t(b)]) <= 0.3;
    if (bins == 45) {
      EXPECT_GE(form.polynomial_bins(), moderate);
    }
    Uniforms u{85};
    for (int b = 0; b < bins; ++b)
      for (int k = 0; k <= 2000; ++k) {
        const double r = k < 1000 ? k / 1000.0 : u(), tilt = model.alpha_tilt[std::size_t(b)];
        const double c0 = std::cos(model.alpha_edges[std::size_t(b)]), c1 = std::cos(model.alpha_edges[std::size_t(b) + 1]);
        const double exact = std::acos(c0 + tilt_quantile(tilt, r) * (c1 - c0));
        const Vec3 p = form.exit_point(b, r);
        ASSERT_NEAR(std::atan2(p.x, p.z), exact, StrideForm::kAngleError + 1e-14) << bins << " bins, bin " << b << " r " << r;
        ASSERT_NEAR(length(p), 1, 1e-15);
      }
  }
}

TEST(Stride, KernelsAgreeWithLibm) {
  for (double t = -0.15; t <= 0.15; t += 1e-4) ASSERT_NEAR(atan_near_zero(t), std::atan(t), 4e-17) << t;
  EXPECT_EQ(atan_near_zero(0.5), std::atan(0.5));
  for (double a = -20; a <= 20; a += 1.3e-3) {
    double s, c;
    sincos_angle(a, s, c);
    ASSERT_NEAR(s, std::sin(a), 1e-14) << a;
    ASSERT_NEAR(c, std::cos(a), 1e-14) << a;
  }
}

}  // namespace
}  // namespace stf
