// A path crossing a big sphere of homogeneous medium in shell-transport strides.
//
// It starts at the centre heading +z. At each point the free radius is the distance to the
// medium's boundary; stf::find_entry picks the largest precomputed sphere that fits there,
// and the path jumps to that sphere's exit point and direction, sampled from its model, its
// throughput multiplied by the escape probability. When no sphere fits (too close to the
// boundary) a renderer continues with ordinary volume path tracing; here the walk stops.
//
//   walk_medium PACK [MEDIUM] [SIGMA_T] [BIG_RADIUS] [PATHS]
#include <stf/lookup.h>
#include <stf/pack.h>
#include <stf/sampler.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <random>

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: walk_medium PACK [MEDIUM] [SIGMA_T] [BIG_RADIUS] [PATHS]\n");
    return 2;
  }
  std::vector<stf::PackEntry> pack;
  std::string error;
  if (!stf::read_pack_file(argv[1], pack, error) || pack.empty()) {
    std::fprintf(stderr, "walk_medium: %s\n", error.empty() ? "empty pack" : error.c_str());
    return 1;
  }
  const std::string medium = argc > 2 ? argv[2] : pack.front().name;
  // A name stands for one medium in a pack (stf::pack_entries_error); its spheres are then
  // found by that medium's albedo and g.
  const auto named = std::find_if(pack.begin(), pack.end(), [&](const stf::PackEntry& e) { return e.name == medium; });
  if (named == pack.end()) {
    std::fprintf(stderr, "walk_medium: the pack has no medium '%s' (usage: walk_medium PACK [MEDIUM] ...)\n", medium.c_str());
    return 2;
  }
  const double albedo = named->model.albedo, g = named->model.g;
  const double sigma_t = argc > 3 ? std::atof(argv[3]) : 10.0;
  const double big_radius = argc > 4 ? std::atof(argv[4]) : 20.0;
  const int paths = argc > 5 ? std::atoi(argv[5]) : 1000;
  // One sampler per pack entry, built once (they are const and thread-safe).
  std::map<const stf::PackEntry*, stf::ShellSampler> samplers;
  for (const stf::PackEntry& e : pack) samplers.emplace(&e, stf::ShellSampler(e.model));

  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double strides = 0, throughput = 0, distance = 0;
  for (int p = 0; p < paths; ++p) {
    stf::Vec3 x{0, 0, 0}, w{0, 0, 1};
    double weight = 1, radius = 0;
    while (const stf::PackEntry* e = stf::find_entry(pack, albedo, g, sigma_t, big_radius - stf::length(x), radius)) {
      const stf::ShellSampler& sampler = samplers.at(e);
      stf::WorldExit exit = sampler.sample_world(x, w, radius, u(rng), u(rng), u(rng), u(rng));
      x = exit.point;
      w = exit.direction;
      weight *= sampler.escape_probability();
      strides += 1;
    }
    throughput += weight;
    distance += stf::length(x);
  }
  std::printf("walk_medium: %s, %d paths, %.2f strides per path, mean throughput %.4g, mean distance from "
              "the centre %.4g (boundary at %.4g)\n",
              medium.c_str(), paths, strides / paths, throughput / paths, distance / paths, big_radius);
  return 0;
}
