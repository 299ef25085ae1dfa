// The stiff and extreme sweep: g x tau x albedo through precompute, fit, pack and sample.
// Every number must be finite, every limit physical. Diffusive cases (tau = 1000 would need
// ~5e5 collisions per path) run under a collision cap whose truncated weight is booked. The
// table printed (case, seconds, escape probability) is for reading, not asserted on.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>

#include "fit_table.h"
#include "precompute.h"
#include "rng.h"
#include "stf/pack.h"
#include "stf/sampler.h"

namespace stf {
namespace {

const double kGs[] = {-0.9999, -0.9, 0.0, -1e-8, 1e-8, 0.9, 0.9999};
const double kTaus[] = {1e-6, 1e-2, 1, 10, 100, 1000};
const double kAlbedos[] = {0, 1e-6, 0.5, 0.999, 1};
constexpr std::int64_t kPaths = 400;
constexpr std::int64_t kCap = 20000;  // collisions per path; the rest is truncated weight

struct Outcome {
  double escape = 0, seconds = 0;
};

bool finite(const std::vector<double>& v) {
  for (double x : v)
    if (!std::isfinite(x)) return false;
  return true;
}

Outcome run_case(double g, double tau, double albedo) {
  auto start = std::chrono::steady_clock::now();
  PrecomputeSettings s;
  s.paths = kPaths;
  s.alpha_bins = 9;
  s.grid = "healpix:2";
  s.max_scatter = kCap;
  s.seed = 5;
  s.threads = 2;
  Table t = *precompute({albedo * tau, (1 - albedo) * tau, g, 1}, s);
  EXPECT_EQ(t.escaped_weight + t.absorbed_weight + t.truncated_weight, double(kPaths));
  EXPECT_TRUE(finite(t.weight_half[0]) && finite(t.weight_half[1]));

  fit::FitSettings fs = fit::parse_model_spec("vmf:2");
  fs.threads = 2;
  StfModel m = fit::fit_table(t, fs);
  for (const VmfLobe& l : m.vmf) EXPECT_TRUE(std::isfinite(l.kappa) && std::isfinite(l.weight) && std::isfinite(l.mean.z));

  std::vector<PackEntry> entries;
  std::string error;
  std::vector<std::uint8_t> pack = write_pack({{"stress", m}});
  EXPECT_TRUE(read_pack(pack.data(), pack.size(), entries, error)) << error;
  ShellSampler sampler(entries.front().model);
  std::uint64_t state = 9;
  auto u = [&] { return double(splitmix64(state) >> 11) * 0x1p-53; };
  for (int i = 0; i < 200; ++i) {
    ExitSample x = sampler.sample(u(), u(), u(), u());
    EXPECT_TRUE(std::isfinite(x.pdf) && x.pdf > 0);
    EXPECT_TRUE(std::isfinite(x.point.z) && std::isfinite(x.direction.z));
    EXPECT_TRUE(std::isfinite(sampler.pdf(x.point, x.direction)));
  }
  return {t.escaped_weight / double(kPaths),
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()};
}

TEST(StressSweep, FiniteEverywhereAndPhysicalLimits) {
  std::printf("%-9s %-7s %-7s %8s %8s\n", "g", "tau", "albedo", "escape", "seconds");
  for (double g : kGs)
    for (double tau : kTaus) {
      std::vector<double> escape;
      for (double albedo : kAlbedos) {
        SCOPED_TRACE("g " + std::to_string(g) + " tau " + std::to_string(tau) + " albedo " + std::to_string(albedo));
        Outcome o = run_case(g, tau, albedo);
        std::printf("%-9g %-7g %-7g %8.4f %8.3f\n", g, tau, albedo, o.escape, o.seconds);
        escape.push_back(o.escape);
        const double n = double(kPaths), p0 = std::exp(-tau);
        if (albedo == 0) {  // only the unscattered escape: a binomial with p = exp(-tau)
          EXPECT_NEAR(escape.back(), p0, 6 * std::sqrt(p0 * (1 - p0) / n) + 1.0 / n);
        }
        if (tau <= 1e-6) {  // every path leaves unscattered
          EXPECT_EQ(escape.back(), 1.0);
        }
      }
      // Escape falls with falling albedo (the same random numbers: monotone up to noise).
      for (std::size_t i = 1; i < escape.size(); ++i)
        EXPECT_GE(escape[i] + 4 * std::sqrt(0.25 / kPaths), escape[i - 1]) << "g " << g << " tau " << tau;
    }
}

}  // namespace
}  // namespace stf
