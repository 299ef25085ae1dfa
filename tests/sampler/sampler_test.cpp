// Every sampler against its own pdf (chi-square), and the pdf against its measure.
#include "stf/sampler.h"

#include <gtest/gtest.h>

#include <cmath>
#include <utility>

#include "chi2.h"
#include "stf/core/rng.h"
#include "seed.h"
#include "stf/hemisphere.h"
#include "stf/tilt.h"
#include "stf/vmf.h"
#include "test_models.h"
#include "test_numerics.h"

namespace stf {
namespace {

using test::integrate;
using test::Uniforms;
using test::with_uncollided, test::tilted, test::blended, test::blended_by_bin, test::turned, test::hemispherical, test::lifted;

// Directions binned around `axis`: t = 1 - cos(theta) in n_t bins on [0, t_max] (quadratic
// spacing: finer near the axis) plus one tail bin, times n_phi azimuth bins.
struct AxisBins {
  Vec3 axis, b1, b2;
  double t_max;
  int n_t = 24, n_phi = 8;
  AxisBins(Vec3 a, double t) : axis(a), t_max(t) { orthonormal_basis(axis, b1, b2); }
  int bins() const { return (n_t + 1) * n_phi; }
  double t_edge(int i) const { return i > n_t ? 2.0 : t_max * double(i) * i / (double(n_t) * n_t); }
  int bin(const Vec3& d) const {
    double t = 1 - dot(d, axis), phi = std::atan2(dot(d, b2), dot(d, b1));
    phi = phi < 0 ? phi + 2 * kPi : phi;
    int it = t >= t_max ? n_t : std::min(n_t - 1, int(std::sqrt(std::max(0.0, t / t_max)) * n_t));
    return it * n_phi + std::min(n_phi - 1, int(phi / (2 * kPi) * n_phi));
  }
  // Expected probabilities of a density given per steradian: integrated in (t, phi).
  template <typename Pdf>
  std::vector<double> expected(Pdf pdf) const {
    std::vector<double> e(bins());
    for (int it = 0; it <= n_t; ++it)
      for (int ip = 0; ip < n_phi; ++ip) {
        double p0 = 2 * kPi * ip / n_phi, p1 = 2 * kPi * (ip + 1) / n_phi;
        e[it * n_phi + ip] = integrate(
            [&](double t) {
              double s = std::sqrt(std::max(0.0, t * (2 - t)));
              return integrate(
                  [&](double phi) {
                    Vec3 d{s * std::cos(phi), s * std::sin(phi), 1 - t};
                    return pdf(Vec3{d.x * b1.x + d.y * b2.x + d.z * axis.x, d.x * b1.y + d.y * b2.y + d.z * axis.y,
                                    d.x * b1.z + d.y * b2.z + d.z * axis.z});
                  },
                  p0, p1, 4);
            },
            t_edge(it), t_edge(it + 1), 16);
      }
    return e;
  }
};

template <typename Sample, typename Pdf>
test::Chi2Result chi2_directions(Sample sample, Pdf pdf, const AxisBins& bins, int n, std::uint64_t seed) {
  std::vector<double> observed(bins.bins(), 0), expected = bins.expected(pdf);
  Uniforms u{seed};
  for (int i = 0; i < n; ++i) observed[bins.bin(sample(u(), u()))] += 1;
  for (double& e : expected) e *= n;
  return test::chi2_test(observed, expected);
}

TEST(Sampler, VmfLobeMatchesItsPdfChiSquare) {
  const std::uint64_t seed = test::test_seed(51);
  SCOPED_TRACE(test::seed_trace(seed));
  for (double kappa : {0.0, 1e-3, 1.0, 100.0, 1e5}) {
    VmfLobe lobe{1, kappa, normalize({0.3, -0.4, 0.8})};
    AxisBins bins(lobe.mean, std::min(2.0, 30 / std::max(kappa, 1e-9)));
    test::Chi2Result r = chi2_directions([&](double a, double b) { return sample_vmf(lobe, a, b); },
                                         [&](const Vec3& w) { return vmf_pdf(kappa, dot(lobe.mean, w)); }, bins,
                                         400000, seed);
    EXPECT_GT(r.p_value, test::kChi2Alpha) << "kappa " << kappa << ": " << r.describe();
  }
}

TEST(Sampler, DirectionSamplersMatchTheirPdfChiSquare) {
  const std::uint64_t seed = test::test_seed(52);
  SCOPED_TRACE(test::seed_trace(seed));
  for (const StfModel& model : {test::make_vmf_model(), test::make_sh_model(), hemispherical(test::make_vmf_model())}) {
    ShellSampler s(model);
    for (int bin : {0, 1, 2}) {
      AxisBins bins({0, 0, 1}, 2.0);
      bins.n_t = 16;
      test::Chi2Result r = chi2_directions([&](double a, double b) { return s.sample_direction(bin, a, b); },
                                           [&](const Vec3& w) { return s.direction_pdf(bin, w); }, bins, 400000, seed + bin);
      EXPECT_GT(r.p_value, test::kChi2Alpha) << (model.kind == ModelKind::kVmf ? "vmf" : "sh") << " bin " << bin << ": " << r.describe();
    }
  }
}


// The whole sample: alpha bin, the position of cos(alpha) inside it, beta, and the direction
// relative to the exit point, against the pdf's own marginals; the uncollided delta as one more
// histogram bin of probability uncollided_fraction.
TEST(Sampler, FullSampleMatchesPdfChiSquare) {
  const std::uint64_t seed = test::test_seed(53);
  SCOPED_TRACE(test::seed_trace(seed));
  for (const StfModel& model : {test::make_vmf_model(), test::make_sh_model(), with_uncollided(test::make_vmf_model()),
                               hemispherical(with_uncollided(test::make_vmf_model())),
                               tilted(with_uncollided(test::make_vmf_model())), tilted(test::make_sh_model()),
                               blended(tilted(hemispherical(with_uncollided(test::make_vmf_model())))),
                               blended(test::make_sh_model()), blended(tilted(test::make_vmf_model()), 2),
                               blended(tilted(test::make_vmf_model()), 3),
                               blended_by_bin(tilted(hemispherical(with_uncollided(test::make_vmf_model()))))}) {
    ShellSampler s(model);
    const int bins = model.bins(), sub = 3, quarters = 4, n = 600000;
    AxisBins dir({0, 0, 1}, 2.0);
    dir.n_t = 6;
    dir.n_phi = 4;
    // Expected: P(bin) * P(area part k of the band) * 1/4 (beta) * P(direction cell | bin, part),
    // with P(part k) the integral of the tilted density over it (1/sub untilted); in blended
    // bins of width h the direction density at area fraction v mixes the bins j by the hats
    // max(0, 1 - |b + v - j - 1/2| / h), normalised over the bins that exist.
    std::vector<std::vector<double>> d(bins);
    for (int b = 0; b < bins; ++b) d[b] = dir.expected([&](const Vec3& w) { return s.direction_pdf(b, w); });
    std::vector<double> expected, observed(bins * sub * quarters * dir.bins() + 1, 0);
    for (int b = 0; b < bins; ++b) {
      const double smooth = model.alpha_probability[b] - (b == 0 ? model.uncollided_fraction : 0);
      for (int k = 0; k < sub * quarters; ++k) {
        const double v0 = double(k / quarters) / sub, v1 = double(k / quarters + 1) / sub;
        const int h = model.blend_width(b);
        auto hat = [&](int j, double v) {
          if (h == 0) return j == b ? 1.0 : 0.0;
          double total = 0;
          for (int i = 0; i < bins; ++i) total += std::max(0.0, 1 - std::abs(b + v - i - 0.5) / h);
          return std::max(0.0, 1 - std::abs(b + v - j - 0.5) / h) / total;
        };
        std::vector<double> mix(d[b].size(), 0.0);
        for (int j = 0; j < bins; ++j) {
          // Both sides of the bin's middle apart: the hats have their kinks there.
          double share = 0;
          for (auto [a, z] : {std::pair{v0, std::min(v1, 0.5)}, std::pair{std::max(v0, 0.5), v1}})
            if (z > a) share += integrate([&](double v) { return hat(j, v) * tilt_density(model.tilt(b), v); }, a, z, 64);
          for (std::size_t c = 0; c < mix.size(); ++c) mix[c] += share * d[j][c];
        }
        for (double p : mix) expected.push_back(n * smooth / quarters * p);
      }
    }
    expected.push_back(n * model.uncollided_fraction);
    if (model.uncollided_fraction == 0) expected.pop_back(), observed.pop_back();
    Uniforms u{seed};
    for (int i = 0; i < n; ++i) {
      ExitSample x = s.sample(u(), u(), u(), u());
      if (x.component == kUncollided) {
        ASSERT_EQ(x.point.z, 1);
        ASSERT_EQ(x.direction.z, 1);
        ASSERT_EQ(x.pdf, model.uncollided_fraction);
        observed.back() += 1;
        continue;
      }
      double alpha = std::atan2(std::hypot(x.point.x, x.point.y), x.point.z);
      int b = std::min(bins - 1, int(alpha / kPi * bins));
      double c0 = std::cos(model.alpha_edges[b]), c1 = std::cos(model.alpha_edges[b + 1]);
      int k = std::min(sub - 1, int((c0 - x.point.z) / (c0 - c1) * sub));
      double beta = std::atan2(x.point.y, x.point.x);
      beta = beta < 0 ? beta + 2 * kPi : beta;
      int q = std::min(quarters - 1, int(beta / (2 * kPi) * quarters));
      double cb = std::cos(-beta), sb = std::sin(-beta);
      Vec3 local{cb * x.direction.x - sb * x.direction.y, sb * x.direction.x + cb * x.direction.y, x.direction.z};
      observed[((b * sub + k) * quarters + q) * dir.bins() + dir.bin(local)] += 1;
    }
    test::Chi2Result r = test::chi2_test(observed, expected);
    EXPECT_GT(r.p_value, test::kChi2Alpha) << r.describe();
  }
}

TEST(Sampler, PdfOfASampleIsTheReturnedPdf) {
  for (const StfModel& model : {test::make_vmf_model(), test::make_sh_model(), with_uncollided(test::make_vmf_model()),
                               hemispherical(with_uncollided(test::make_vmf_model())), tilted(test::make_vmf_model()),
                               blended(tilted(test::make_vmf_model())), blended(tilted(test::make_vmf_model()), 3),
                               turned(hemispherical(test::make_vmf_model())), blended(turned(tilted(test::make_vmf_model())), 2),
                               turned(test::make_sh_model()), lifted(with_uncollided(test::make_vmf_model())),
                               blended(turned(tilted(lifted(test::make_vmf_model()))), 2)}) {
    ShellSampler s(model);
    Uniforms u{54};
    for (int i = 0; i < 20000; ++i) {
      ExitSample x = s.sample(u(), u(), u(), u());
      if (x.component == kUncollided) continue;  // a discrete probability, checked above
      ASSERT_GT(x.pdf, 0);
      ASSERT_NEAR(s.pdf(x.point, x.direction), x.pdf, 1e-9 * x.pdf);
      ASSERT_NEAR(length(x.point), 1, 1e-12);
      ASSERT_NEAR(length(x.direction), 1, 1e-12);
    }
  }
}

// Stratified quadrature over the (4 pi)^2 domain. The pdf is constant in the exit point
// within an alpha band but for the rotation by beta, so each band is its area times the
// beta-average at its middle; directions on a fine (z, phi) midpoint grid, which refines the
// SH model's equal-area cells exactly and resolves the kappa = 80 lobe to ~1e-4.
TEST(Sampler, PdfIntegratesToOne) {
  for (const StfModel& model : {test::make_vmf_model(), test::make_sh_model(), with_uncollided(test::make_vmf_model()),
                               hemispherical(with_uncollided(test::make_vmf_model())),
                               lifted(with_uncollided(test::make_vmf_model()))}) {
    ShellSampler s(model);
    const int nb = 3, nz = 384, nphi = 768;
    double total = 0;
    for (int bin = 0; bin < model.bins(); ++bin) {
      double a0 = model.alpha_edges[bin], a1 = model.alpha_edges[bin + 1], alpha = 0.5 * (a0 + a1);
      double band = 2 * kPi * (std::cos(a0) - std::cos(a1));
      for (int j = 0; j < nb; ++j) {
        double beta = 2 * kPi * (j + 0.5) / nb;
        Vec3 y{std::sin(alpha) * std::cos(beta), std::sin(alpha) * std::sin(beta), std::cos(alpha)};
        double directions = 0;
        for (int k = 0; k < nz; ++k) {
          double wz = -1 + 2 * (k + 0.5) / nz, wr = std::sqrt(1 - wz * wz);
          for (int l = 0; l < nphi; ++l) {
            double phi = 2 * kPi * (l + 0.5) / nphi;
            directions += s.pdf(y, {wr * std::cos(phi), wr * std::sin(phi), wz});
          }
        }
        total += band / nb * directions * 4 * kPi / (nz * nphi);
      }
    }
    // The smooth part's density integrates to its probability; the delta holds the rest.
    EXPECT_NEAR(total, 1 - model.uncollided_fraction, 1e-3) << (model.kind == ModelKind::kVmf ? "vmf" : "sh");
  }
}

// Every kind of model a stride's exit can come from.
std::vector<std::pair<std::string, StfModel>> exit_models() {
  return {{"vmf", test::make_vmf_model()},
          {"sh", test::make_sh_model()},
          {"hemispherical", hemispherical(test::make_vmf_model())},
          {"lifted", lifted(test::make_vmf_model())},
          {"blended tilted", blended(tilted(test::make_vmf_model()))},
          {"turned", turned(test::make_vmf_model())},
          {"lifted turned blended", blended(turned(lifted(test::make_vmf_model())))},
          {"blended sh", blended(test::make_sh_model())}};
}

// The exit's direction density (what next-event estimation at a stride's exit weighs by) is a
// density of directions at every exit point: it integrates to 1.
TEST(Sampler, ExitDirectionDensityIntegratesToOneAtEveryExitPoint) {
  for (const auto& [name, model] : exit_models()) {
    ShellSampler s(model);
    for (double alpha : {0.1, 0.7, 1.5, 2.4, 3.0}) {
      const Vec3 y{std::sin(alpha) * std::cos(1.3), std::sin(alpha) * std::sin(1.3), std::cos(alpha)};
      // Midpoints in polar angle about y (even in angle near the pole, where lifted and sharp
      // lobes peak; a lifted density's horizon about y falls between slices).
      const Frame f = Frame::around(y);
      const int ntheta = 512, nphi = 1024;
      double total = 0;
      for (int k = 0; k < ntheta; ++k) {
        const double theta = kPi * (k + 0.5) / ntheta, st = std::sin(theta), ct = std::cos(theta);
        for (int l = 0; l < nphi; ++l) {
          const double phi = 2 * kPi * (l + 0.5) / nphi;
          total += st * s.exit_direction_pdf(y, f.to_world({st * std::cos(phi), st * std::sin(phi), ct}));
        }
      }
      EXPECT_NEAR(total * kPi / ntheta * 2 * kPi / nphi, 1, 1e-3) << name << " at alpha " << alpha;
      // The world-space form is the same density about a stride's start and heading.
      const Vec3 x{0.3, -1.2, 2.0}, d = normalize(Vec3{0.2, 0.9, -0.4}), w = normalize(Vec3{-0.5, 0.1, 0.7});
      const Frame frame = Frame::around(d);
      EXPECT_NEAR(s.exit_direction_pdf_world(x, d, 0.7, x + 0.7 * frame.to_world(y), frame.to_world(w)),
                  s.exit_direction_pdf(y, w), 1e-9 * (1 + s.exit_direction_pdf(y, w)))
          << name;
    }
  }
}

// The stride form's draw at one exit point (its first uniform, which picks the outcome and the
// exit angle, held fixed; the azimuth and the direction free) follows the exit's direction
// density, in the exit point's x-z frame (chi-square), for every kind of model.
TEST(Sampler, TheStrideDrawAtAnExitPointFollowsTheExitDirectionDensity) {
  const std::uint64_t seed = test::test_seed(57);
  SCOPED_TRACE(test::seed_trace(seed));
  for (const auto& [name, model] : exit_models()) {
    const ShellSampler s(model);
    int points = 0;
    for (double u0 : {0.23, 0.51, 0.87}) {
      Uniforms u{seed + std::uint64_t(u0 * 100)};
      const auto draw = [&] {
        bool first = true;
        return s.stride_form().local([&] { return std::exchange(first, false) ? u0 : u(); });
      };
      const Stride one = draw();
      if (one.component != kSmooth) continue;
      ++points;
      const double alpha = std::acos(std::clamp(one.point.z, -1.0, 1.0));
      const Vec3 y{std::sin(alpha), 0, std::cos(alpha)};
      AxisBins bins(y, 2.0);
      bins.n_t = 16;
      const int n = 200000;
      std::vector<double> observed(bins.bins(), 0), expected = bins.expected([&](const Vec3& w) { return s.exit_direction_pdf(y, w); });
      for (int i = 0; i < n; ++i) {
        const Stride e = draw();
        const double beta = std::atan2(e.point.y, e.point.x), cb = std::cos(beta), sb = std::sin(beta);
        observed[bins.bin({cb * e.direction.x + sb * e.direction.y, cb * e.direction.y - sb * e.direction.x, e.direction.z})] += 1;
      }
      for (double& x : expected) x *= n;
      const test::Chi2Result r = test::chi2_test(observed, expected);
      EXPECT_GT(r.p_value, test::kChi2Alpha) << name << " at u0 " << u0 << " (alpha " << alpha << "): " << r.describe();
    }
    EXPECT_GE(points, 2) << name;
  }
}

// E[1_A / pdf] = |A| where the pdf is positive on A: A = exit points with alpha in bins 1..2
// (any beta), directions in the upper hemisphere: |A| = 2 pi (cos a1 - cos a3) * 2 pi.
// With tilted bins the pdf varies with the exit point inside a band; the measure does not.
TEST(Sampler, InversePdfRecoversTheMeasureOfRegions) {
  for (const StfModel& model : {test::make_vmf_model(), tilted(test::make_vmf_model()), blended(tilted(test::make_vmf_model())),
                                blended(tilted(test::make_vmf_model()), 2), turned(tilted(test::make_vmf_model())),
                                blended(turned(tilted(test::make_vmf_model())), 2),
                                blended_by_bin(turned(tilted(test::make_vmf_model())))}) {
    ShellSampler s(model);
    const StfModel& m = s.model();
    const double measure = 2 * kPi * (std::cos(m.alpha_edges[1]) - std::cos(m.alpha_edges[3])) * 2 * kPi;
    Uniforms u{55};
    const int n = 400000;
    double sum = 0, sum2 = 0;
    for (int i = 0; i < n; ++i) {
      ExitSample x = s.sample(u(), u(), u(), u());
      double alpha = std::acos(std::clamp(x.point.z, -1.0, 1.0));
      bool in = alpha >= m.alpha_edges[1] && alpha < m.alpha_edges[3] && x.direction.z > 0;
      double v = in ? 1 / x.pdf : 0;
      sum += v;
      sum2 += v * v;
    }
    double mean = sum / n, error = std::sqrt((sum2 / n - mean * mean) / n);
    EXPECT_NEAR(mean, measure, 6 * error) << "standard error " << error << (m.alpha_tilt.empty() ? "" : ", tilted")
                                          << ", blend " << m.alpha_blend << (m.alpha_turn.empty() ? "" : ", turned");
  }
}

// The tilted law's three forms against each other and against quadrature of the density.
TEST(Tilt, DensityMassAndQuantileAgree) {
  for (double tilt : {-kMaxTilt, -30.0, -2.5, -1e-9, 0.0, 1e-7, 0.7, 25.0, kMaxTilt}) {
    EXPECT_NEAR(integrate([&](double v) { return tilt_density(tilt, v); }, 0, 1, 256), 1, 1e-10) << tilt;
    for (double u0 : {0.0, 0.1, 0.45}) {
      for (double u1 : {0.5, 0.93, 1.0}) {
        const double q = integrate([&](double v) { return tilt_density(tilt, v); }, u0, u1, 256);
        EXPECT_NEAR(tilt_mass(tilt, u0, u1), q, 1e-10 + 1e-9 * q) << tilt << " " << u0 << " " << u1;
      }
    }
    for (double xi : {0.0, 1e-12, 0.3, 0.5, 0.999, 1.0}) {
      const double u = tilt_quantile(tilt, xi);
      ASSERT_TRUE(u >= 0 && u <= 1) << tilt << " " << xi;
      // Where the density is tiny the distribution function is flat and u is ill-determined.
      EXPECT_NEAR(tilt_mass(tilt, 0, u), xi, 1e-12) << tilt << " " << xi;
    }
  }
  EXPECT_EQ(tilt_density(0, 0.3), 1);
  EXPECT_EQ(tilt_quantile(0, 0.3), 0.3);
}

TEST(Sampler, WorldSpaceSamplesAreRotatedLocalOnes) {
  ShellSampler s(test::make_vmf_model());
  Uniforms u{56};
  const int bins = s.model().bins(), n = 300000;
  std::vector<double> observed(bins, 0), expected(bins);
  for (int b = 0; b < bins; ++b) expected[b] = n * s.model().alpha_probability[b];
  for (int i = 0; i < n; ++i) {
    Vec3 start{u() * 10, u() * 10, u() * 10}, heading = sample_vmf({1, 0, {0, 0, 1}}, u(), u());
    double radius = 0.5 + 3 * u();
    WorldExit w = s.sample_world(start, heading, radius, u(), u(), u(), u());
    Vec3 d{(w.point.x - start.x) / radius, (w.point.y - start.y) / radius, (w.point.z - start.z) / radius};
    ASSERT_NEAR(length(d), 1, 1e-9);
    ASSERT_NEAR(s.pdf_world(start, heading, radius, w.point, w.direction), w.pdf, 1e-8 * w.pdf);
    // The exit point's angle to the heading is the local alpha: same marginal.
    double alpha = std::acos(std::clamp(dot(d, heading), -1.0, 1.0));
    observed[std::min(bins - 1, int(alpha / kPi * bins))] += 1;
  }
  test::Chi2Result r = test::chi2_test(observed, expected);
  EXPECT_GT(r.p_value, test::kChi2Alpha) << r.describe();
}

// jump() is the stride form's draw (stride_test checks its distribution against the pdf) from
// u0 .. u3 and then a stream seeded from them, for every component (the uncollided delta
// included); its pdf is 0. (To rounding: the library's kernels may fuse multiply-adds this
// file's do not.)
TEST(Sampler, JumpIsTheStrideFormsDraw) {
  for (const StfModel& model : {test::make_vmf_model(), test::make_sh_model(), with_uncollided(test::make_vmf_model()),
                               hemispherical(with_uncollided(test::make_vmf_model())),
                               lifted(with_uncollided(test::make_vmf_model()))}) {
    ShellSampler s(model);
    Uniforms u{57};
    for (int i = 0; i < 20000; ++i) {
      Vec3 start{u(), u(), u()}, heading = sample_vmf({1, 0, {0, 0, 1}}, u(), u());
      double radius = 0.5 + u(), u0 = u(), u1 = u(), u2 = u(), u3 = u();
      const double first[4] = {u0, u1, u2, u3};
      RetryStream more(u0, u1, u2, u3);
      int taken = 0;
      const Stride form = s.stride_form().jump(start, heading, radius, [&] { return taken < 4 ? first[taken++] : more.uniform(); });
      WorldExit jump = s.jump(start, heading, radius, u0, u1, u2, u3);
      ASSERT_EQ(jump.component, form.component);
      ASSERT_NEAR(jump.point.x, form.point.x, 1e-12);
      ASSERT_NEAR(jump.point.y, form.point.y, 1e-12);
      ASSERT_NEAR(jump.point.z, form.point.z, 1e-12);
      ASSERT_NEAR(jump.direction.x, form.direction.x, 1e-12);
      ASSERT_NEAR(jump.direction.y, form.direction.y, 1e-12);
      ASSERT_NEAR(jump.direction.z, form.direction.z, 1e-12);
      ASSERT_EQ(jump.pdf, 0);
    }
  }
}

TEST(Sampler, ExtremeUniformsStayFinite) {
  for (const StfModel& model : {test::make_vmf_model(), test::make_sh_model()}) {
    ShellSampler s(model);
    const double us[] = {0.0, 1e-300, 0.5, std::nextafter(1.0, 0.0)};
    for (double a : us)
      for (double b : us)
        for (double c : us)
          for (double d : us) {
            ExitSample x = s.sample(a, b, c, d);
            ASSERT_TRUE(std::isfinite(x.pdf) && x.pdf > 0);
            ASSERT_TRUE(std::isfinite(x.point.x + x.point.y + x.point.z + x.direction.x + x.direction.y + x.direction.z));
          }
  }
}

// The outward factor of hemispherical lobes: its closed form against a plain average over the
// bin's exit angles, and the trigonometry-free fast path against the closed form.
TEST(Hemisphere, OutwardFactorIsTheMeanOutwardCosineOverTheBin) {
  std::uint64_t seed = 91;
  Uniforms u{seed};
  for (auto [a0, a1] : {std::pair(0.0, 0.07), std::pair(0.6, 0.67), std::pair(1.0, 2.5), std::pair(0.0, kPi)}) {
    const OutwardBin fast(a0, a1);
    for (int i = 0; i < 2000; ++i) {
      const double z = 2 * u() - 1, phi = 2 * kPi * u(), r = std::sqrt(1 - z * z);
      const Vec3 w{r * std::cos(phi), r * std::sin(phi), z};
      double mean = 0;
      const int n = 4000;
      for (int k = 0; k < n; ++k) {
        const double a = a0 + (k + 0.5) / n * (a1 - a0);
        mean += std::max(0.0, w.x * std::sin(a) + w.z * std::cos(a)) / n;
      }
      const double exact = mean_exit_cosine(w, a0, a1);
      ASSERT_NEAR(exact, mean, 1e-6) << a0 << " " << a1;
      ASSERT_NEAR(fast(w), exact, 1e-12) << a0 << " " << a1;
      ASSERT_GE(exact, 0);
      ASSERT_LE(exact, 1);
    }
  }
}

}  // namespace
}  // namespace stf
