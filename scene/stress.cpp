#include "stf/scene/stress.h"

#include <chrono>
#include <cmath>
#include <cstdio>

#include "stf/fit/fit_table.h"
#include "stf/precompute/precompute.h"
#include "stf/core/rng.h"
#include "stf/pack.h"
#include "stf/sampler.h"
#include "stf/core/clock.h"

namespace stf::scene {

std::vector<StressCase> stress_cases() {
  std::vector<StressCase> cases;
  for (double g : {-0.9999, -0.9, 0.0, -1e-8, 1e-8, 0.9, 0.9999})
    for (double tau : {1e-6, 1e-2, 1.0, 10.0, 100.0, 1000.0})
      for (double albedo : {0.0, 1e-6, 0.5, 0.999, 1.0}) cases.push_back({g, tau, albedo});
  return cases;
}

namespace {
constexpr double kPoorFitChi2Dof = 100;

void check(bool ok, const char* what, StressResult& r) {
  if (ok || !r.finite) return;
  r.finite = false;
  r.status = std::string("not finite: ") + what;
}
}  // namespace

StressResult run_stress_case(const StressCase& c, long paths, long max_scatter, int threads) {
  auto start = std::chrono::steady_clock::now();
  StressResult r;
  r.c = c;
  PrecomputeSettings s;
  s.paths = paths;
  s.alpha_bins = 9;
  s.grid = "healpix:2";
  s.max_scatter = max_scatter;
  s.seed = 5;
  s.run.threads = threads;
  Table t = *precompute({c.albedo * c.tau, (1 - c.albedo) * c.tau, c.g, 1}, s);
  for (int h = 0; h < 2; ++h)
    for (double w : t.weight_half[h]) check(std::isfinite(w), "table", r);
  r.escape = t.escaped_weight / double(paths);
  r.truncated = t.truncated_weight / double(paths);

  fit::FitSettings fs = fit::parse_model_spec("vmf:2");
  fs.run.threads = threads;
  fit::FitReport report;
  StfModel m = fit::fit_table(t, fs, &report);
  for (const VmfLobe& l : m.vmf) check(std::isfinite(l.kappa) && std::isfinite(l.weight) && std::isfinite(l.mean.z), "model", r);
  double escapes = 0;
  for (const fit::BinDiagnostics& d : report.bins) {
    if (d.chi2_dof < 0) continue;  // not fitted to its own escapes
    r.fit_chi2_dof += d.escapes * d.chi2_dof;
    escapes += d.escapes;
  }
  r.fit_chi2_dof = escapes > 0 ? r.fit_chi2_dof / escapes : 0;
  check(std::isfinite(r.fit_chi2_dof), "chi2/dof", r);
  // A fit this far off its own table is not ok, even if every number is finite.
  if (r.finite && r.fit_chi2_dof > kPoorFitChi2Dof) r.status = "poor fit";

  std::vector<PackEntry> entries;
  std::string error;
  std::vector<std::uint8_t> pack = write_pack({{"stress", m}});
  check(read_pack(pack.data(), pack.size(), entries, error), "pack", r);
  if (r.finite) {
    ShellSampler sampler(entries.front().model);
    std::uint64_t state = 9;
    auto u = [&] { return double(splitmix64(state) >> 11) * 0x1p-53; };
    for (int i = 0; i < 200; ++i) {
      ExitSample x = sampler.sample(u(), u(), u(), u());
      check(std::isfinite(x.pdf) && x.pdf > 0 && std::isfinite(x.point.z) && std::isfinite(x.direction.z), "sample", r);
      check(std::isfinite(sampler.pdf(x.point, x.direction)), "pdf", r);
    }
  }
  if (r.status.empty()) r.status = "ok";
  r.seconds = seconds_since(start);
  return r;
}

std::string stress_table_header() {
  char line[160];
  std::snprintf(line, sizeof line, "%-9s %-7s %-7s %8s %8s %9s %9s  %s", "g", "tau", "albedo", "seconds", "escape",
                "truncated", "chi2/dof", "status");
  return line;
}

std::string stress_table_row(const StressResult& r) {
  char line[200];
  std::snprintf(line, sizeof line, "%-9g %-7g %-7g %8.3f %8.4f %9.4f %9.3g  %s", r.c.g, r.c.tau, r.c.albedo, r.seconds,
                r.escape, r.truncated, r.fit_chi2_dof, r.status.c_str());
  return line;
}

}  // namespace stf::scene
