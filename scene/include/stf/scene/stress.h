// The stiff and extreme sweep: g x tau x albedo through precompute, fit, pack and sample.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace stf::scene {

struct StressCase {
  double g, tau, albedo;
};

struct StressResult {
  StressCase c;
  double seconds = 0;
  double escape = 0, truncated = 0;  // fractions of paths
  double fit_chi2_dof = 0;           // escape-weighted over bins with escapes
  bool finite = true;                // every table entry, model parameter, sample and pdf
  std::string status;                // "ok" or what was not finite
};

// g in {-0.9999, -0.9, 0, -1e-8, 1e-8, 0.9, 0.9999} x tau in {1e-6, 1e-2, 1, 10, 100, 1000}
// x albedo in {0, 1e-6, 0.5, 0.999, 1}.
std::vector<StressCase> stress_cases();

// One case: `paths` paths capped at `max_scatter` collisions each (the rest is booked as
// truncated weight), a vmf:2 fit, a pack round trip and 200 samples with their pdfs.
StressResult run_stress_case(const StressCase& c, long paths, long max_scatter, int threads);

std::string stress_table_header();
std::string stress_table_row(const StressResult& r);

}  // namespace stf::scene
