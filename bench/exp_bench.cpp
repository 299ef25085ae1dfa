// The lobe integrals' exponentials: ns per exponential taken one call per point (std::exp, as
// the fit took them before) and in batches of 64 (exp_in_place), on exponents spread over the
// 40 e-folds a lobe reaches, in the same run, in turns; best of 15 repeats. JSON on stdout (and in --out FILE).
//   exp_bench [--out FILE]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "stf/fit/exp_in_place.h"

namespace {

constexpr int kBatch = 64, kPoints = 1 << 16, kRounds = 50;

// ns per exponential of each run, best of 15 repeats taken in turns: the machine is shared, the
// fastest repeat is the one least disturbed, and taking them in turns shares the disturbances.
template <class One, class Batched>
void best_ns(One one, Batched batched, double& one_ns, double& batched_ns) {
  auto time = [](auto run) {
    const auto start = std::chrono::steady_clock::now();
    for (int round = 0; round < kRounds; ++round) run(round);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return s * 1e9 / (double(kRounds) * kPoints);
  };
  one_ns = batched_ns = 1e300;
  for (int repeat = 0; repeat < 15; ++repeat) {
    one_ns = std::min(one_ns, time(one));
    batched_ns = std::min(batched_ns, time(batched));
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<double> exponent(kPoints), out(kPoints);
  for (int i = 0; i < kPoints; ++i) exponent[std::size_t(i)] = -40.0 * ((i * 40503u) % kPoints) / kPoints;
  double sink = 0;
  auto one_call = [&](int round) {
    const double shift = round * 1e-12;
    for (int i = 0; i < kPoints; ++i) out[std::size_t(i)] = std::exp(exponent[std::size_t(i)] - shift);
    sink += out[7];
  };
  auto in_batches = [&](int round) {
    const double shift = round * 1e-12;
    for (int i = 0; i < kPoints; i += kBatch) {
      for (int k = 0; k < kBatch; ++k) out[std::size_t(i + k)] = exponent[std::size_t(i + k)] - shift;
      stf::fit::exp_in_place(&out[std::size_t(i)], kBatch);
    }
    sink += out[7];
  };
  double one = 0, batched = 0;
  best_ns(one_call, in_batches, one, batched);
  char json[256];
  std::snprintf(json, sizeof json,
                "{\"std_exp_ns\": %.3f, \"exp_in_place_ns\": %.3f, \"speedup\": %.2f, \"batch\": %d, \"check\": %.3g}\n", one,
                batched, one / batched, kBatch, sink);
  std::fputs(json, stdout);
  for (int i = 1; i + 1 < argc; ++i)
    if (!std::strcmp(argv[i], "--out")) std::ofstream(argv[i + 1]) << json;
  return 0;
}
