// A path crossing a big sphere of homogeneous medium in shell-transport strides.
//
// It starts at the centre heading +z. While a whole precomputed sphere fits between the path
// and the boundary, it jumps to that sphere's exit point and direction, sampled from the
// model; each jump multiplies the throughput by the escape probability. Near the boundary a
// renderer would continue with ordinary volume path tracing.
//
//   walk_medium PACK [SIGMA_T] [BIG_RADIUS] [PATHS]
#include <stf/pack.h>
#include <stf/sampler.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: walk_medium PACK [SIGMA_T] [BIG_RADIUS] [PATHS]\n");
    return 2;
  }
  std::vector<stf::PackEntry> entries;
  std::string error;
  if (!stf::read_pack_file(argv[1], entries, error) || entries.empty()) {
    std::fprintf(stderr, "walk_medium: %s\n", entries.empty() && error.empty() ? "empty pack" : error.c_str());
    return 1;
  }
  const stf::ShellSampler sampler(entries.front().model);
  const double sigma_t = argc > 2 ? std::atof(argv[2]) : 10.0;
  const double big_radius = argc > 3 ? std::atof(argv[3]) : 20.0;
  const int paths = argc > 4 ? std::atoi(argv[4]) : 1000;
  // The model's sphere has optical radius tau: in this medium its radius is tau / sigma_t.
  const double stride = sampler.model().tau / sigma_t;

  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double steps = 0, throughput = 0, distance = 0;
  for (int p = 0; p < paths; ++p) {
    stf::Vec3 x{0, 0, 0}, w{0, 0, 1};
    double weight = 1;
    while (big_radius - stf::length(x) >= stride) {
      stf::WorldExit e = sampler.sample_world(x, w, stride, u(rng), u(rng), u(rng), u(rng));
      x = e.point;
      w = e.direction;
      weight *= sampler.escape_probability();
      steps += 1;
    }
    throughput += weight;
    distance += stf::length(x);
  }
  std::printf("walk_medium: %d paths, %.2f strides per path of radius %.4g, mean throughput %.4g, "
              "mean distance from the centre %.4g (boundary at %.4g)\n",
              paths, steps / paths, stride, throughput / paths, distance / paths, big_radius);
  return 0;
}
