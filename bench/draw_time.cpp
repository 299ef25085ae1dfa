// The C++ baseline of bench/python_bench.py: seconds for N draws of `stf sample --seed K` into
// arrays, as stf.Model.sample fills them (one thread). JSON on stdout.
//   draw_time MODEL N [SEED]
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "stf/fit/model_io.h"
#include "stf/sampler.h"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: draw_time MODEL N [SEED]\n");
    return 2;
  }
  const stf::ShellSampler sampler(stf::fit::read_model_or_pack(argv[1]));
  const long n = std::atol(argv[2]);
  const std::uint64_t seed = argc > 3 ? std::strtoull(argv[3], nullptr, 10) : 1;
  std::vector<double> point(3 * std::size_t(n)), direction(3 * std::size_t(n)),
      pdf(static_cast<std::size_t>(n));
  std::vector<signed char> component(static_cast<std::size_t>(n));
  const auto start = std::chrono::steady_clock::now();
  stf::SampleStream stream(seed, 0);
  for (long i = 0; i < n; ++i) {
    const stf::ExitSample s = stream.next(sampler);
    point[3 * i] = s.point.x, point[3 * i + 1] = s.point.y, point[3 * i + 2] = s.point.z;
    direction[3 * i] = s.direction.x, direction[3 * i + 1] = s.direction.y,
                  direction[3 * i + 2] = s.direction.z;
    pdf[i] = s.pdf, component[i] = static_cast<signed char>(s.component);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("{\"draws\": %ld, \"seconds\": %.6f, \"check\": %.17g}\n", n, seconds,
              pdf[std::size_t(n - 1)]);
  return 0;
}
