// How fast could strides be? An upper bound on `stf render`'s speed-up that no model or
// faster sampler can beat: camera paths of the render scene are followed with *ideal*
// strides, where the jump through each sphere is the true transport (a brute-force walk
// inside the sphere, whose collisions are not counted) instead of a draw from a model. What is
// left is the work strides cannot remove: the collisions in the boundary shell where no
// sphere fits, and the number of strides. For a stride that costs c collisions the speed-up is
//   brute collisions / (shell collisions + c strides),
// at most brute / shell for free strides. Reported per optical radius tau and smallest sphere
// (spheres from it up by a constant ratio: 2, as `stf render` packs them, sqrt 2, 2^(1/4), or
// 1 for any radius down to it), with the stride cost at which a 10x speed-up would need strides to come, and the
// share of the strides through each sphere (where a stride's cost matters). Counts are per path that hits the
// sphere, over the scene's whole image. JSON on stdout.
//   stride_bound [HITTING_PATHS]                              the table (albedo 0.999, g 0.8)
//   stride_bound HITTING_PATHS TAU ALBEDO G TAU_MIN RATIO [TAU_MAX]
//                                                             one medium and ladder (sigma_t 100),
//                                                             its spheres up to TAU_MAX
//   stride_bound --scene SCENE.toml PACK [SIZE] [SPP]         a render scene (stf render SCENE.toml):
//                                                             its camera paths by brute force and
//                                                             with ideal strides through PACK's
//                                                             spheres, as stf render --ideal-strides
// In a scene the counts are per camera path (SIZE x SIZE pixels, default 64, SPP each, default
// 16), with the scene's distance grid deciding where spheres fit; PACK is the scene's render pack
// (`stf pack CACHE/*.model.h5` after `stf render SCENE.toml --method stf --cache CACHE`).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include "stf/pack.h"
#include "stf/render/pixel_rng.h"
#include "stf/render/render.h"
#include "stf/render/scene_geometry.h"
#include "stf/render/ladder.h"
#include "sphere_rays.h"
#include "stf/scene/render_scene.h"

namespace {

using stf::Vec3;
using stf::render::CollisionWalk;
using stf::render::PixelRng;

struct Counts {
  double collisions = 0, strides = 0;
  // Strides by sphere: step k of the ladder, the sphere r_min ratio^k (any radius: the octave
  // [r_min 2^k, r_min 2^(k+1)), reported by its lower edge).
  std::array<double, 64> by_step{};
};

// Spheres of optical radius r_min * ratio^k (any radius >= r_min when ratio is 1).
struct Radii {
  double r_min, ratio;
  double r_max = std::numeric_limits<double>::infinity();  // the largest sphere of the ladder
  // The largest optical radius that fits in `free_tau`, 0 when none does.
  double fit(double free_tau) const {
    if (free_tau < r_min) return 0;
    if (ratio == 1) return std::min(free_tau, r_max);
    return std::min(r_max, r_min * std::pow(ratio, std::floor(std::log(free_tau / r_min) / std::log(ratio) + 1e-12)));
  }
  int step(double r) const {
    const double k = ratio == 1 ? std::log2(r / r_min) : std::log(r / r_min) / std::log(ratio);
    return std::clamp(int(std::floor(k + 1e-9)), 0, 63);
  }
  double sphere(int step) const { return r_min * std::pow(ratio == 1 ? 2.0 : ratio, step); }
};

// The true exit of a path that starts at the centre of the sphere of optical radius r about
// x, heading w (a walk whose collisions a stride would not make); throughput takes the
// albedo at each collision, as a stride's escape probability does on average.
void ideal_stride(const stf::Medium& m, double r, Vec3& x, Vec3& w, double& throughput, PixelRng& rng) {
  stf::Medium sphere = m;
  sphere.radius = r / m.sigma_t();
  const CollisionWalk walk(sphere);
  Vec3 y{0, 0, 0};
  while (!walk.leaves_after_flight(y, w, throughput, rng)) {
  }
  // Where the walk crossed the sphere: back along w from y to radius r / sigma_t.
  const double b = stf::dot(y, w), c = stf::dot(y, y) - sphere.radius * sphere.radius;
  const double back = b - std::sqrt(std::max(0.0, b * b - c));  // y - back w is on the sphere
  x = {x.x + y.x - back * w.x, x.y + y.y - back * w.y, x.z + y.z - back * w.z};
}

// One camera path through the medium; `radii` null is brute force.
Counts follow(const stf::Medium& m, const Radii* radii, Vec3 x, Vec3 w, PixelRng& rng) {
  const CollisionWalk walk(m);
  Counts n;
  double throughput = 1;
  for (;;) {
    const double free_tau = m.sigma_t() * (m.radius - stf::length(x));
    const double r = radii ? radii->fit(free_tau) : 0;
    if (r > 0) {
      ideal_stride(m, r, x, w, throughput, rng);
      ++n.strides;
      ++n.by_step[std::size_t(radii->step(r))];
    } else {
      if (walk.leaves_after_flight(x, w, throughput, rng)) return n;
      ++n.collisions;
    }
    if (!stf::render::survives_roulette(throughput, rng)) return n;
  }
}

// Mean counts per hitting path over `paths` camera rays through uniform image positions.
Counts per_path(const stf::Medium& m, const Radii* radii, long paths) {
  Counts sum;
  long hits = 0;
  const bench::SphereCamera camera(m);
  for (long p = 0; hits < paths; ++p) {
    PixelRng rng(7, std::uint64_t(p));
    const double px = 64 * rng.uniform(), py = 64 * rng.uniform();
    Vec3 entry, direction;
    if (!camera.enter(px, py, entry, direction)) continue;
    const Counts n = follow(m, radii, entry, direction, rng);
    sum.collisions += n.collisions, sum.strides += n.strides;
    for (std::size_t k = 0; k < n.by_step.size(); ++k) sum.by_step[k] += n.by_step[k];
    ++hits;
  }
  Counts mean = sum;
  mean.collisions /= double(hits), mean.strides /= double(hits);
  for (double& s : mean.by_step) s /= double(hits);
  return mean;
}



// One row of the table: brute force's collisions against ideal strides' per hitting path.
void print_row(const stf::Medium& m, double brute, const Radii& radii, long paths, bool first) {
  const Counts n = per_path(m, &radii, paths);
  // The stride cost, in collisions, at which the speed-up would be 10 (negative: never).
  const double cost_for_10x = (brute / 10 - n.collisions) / n.strides;
  char largest[32] = "null";
  if (!std::isinf(radii.r_max)) std::snprintf(largest, sizeof largest, "%g", radii.r_max);
  std::printf("%s  {\"tau\": %g, \"albedo\": %g, \"g\": %g, \"smallest_sphere_tau\": %g, \"largest_sphere_tau\": %s, \"radius_ratio\": %.4f, "
              "\"brute_collisions\": %.2f, \"shell_collisions\": %.2f, \"strides\": %.2f, \"speedup_free_strides\": %.2f, "
              "\"stride_cost_for_10x\": %.3f, \"stride_share_by_sphere_tau\": {",
              first ? "" : ",\n", m.radius * m.sigma_t(), m.albedo(), m.g, radii.r_min, largest, radii.ratio, brute, n.collisions,
              n.strides, brute / n.collisions, cost_for_10x);
  // Where strides happen: the share of all strides through each sphere of the ladder.
  const char* separator = "";
  for (std::size_t k = 0; k < n.by_step.size(); ++k)
    if (n.by_step[k] > 0) {
      std::printf("%s\"%g\": %.4f", separator, radii.sphere(int(k)), n.by_step[k] / n.strides);
      separator = ", ";
    }
  std::printf("}}");
  std::fflush(stdout);
}

stf::Medium medium(double tau, double albedo, double g) {
  stf::Medium m;
  m.sigma_s = 100 * albedo, m.sigma_a = 100 - m.sigma_s, m.g = g, m.radius = tau / 100;
  return m;
}

// A render scene's bound: brute force's collisions B per camera path against the shell
// collisions C and strides N of ideal strides through the pack's spheres, and B / (C + c N) at
// stride costs c of 2 to 6 collisions.
int scene_bound(const std::string& scene_file, const std::string& pack_file, int size, long spp) {
  std::vector<stf::PackEntry> pack;
  std::string error;
  if (!stf::read_pack_file(pack_file, pack, error)) {
    std::fprintf(stderr, "stride_bound: %s\n", error.c_str());
    return 2;
  }
  const stf::scene::RenderScene scene = stf::scene::read_render_scene(scene_file);
  const stf::render::SceneGeometry geometry(scene, stf::render::FreeRadius::kGrid);
  stf::render::ImageSettings settings;
  settings.width = settings.height = size, settings.spp = spp;
  const stf::render::Image brute = stf::render::render(scene, stf::render::ScenePaths(scene, geometry), settings);
  const stf::render::ScenePaths ideal_paths(scene, geometry, &pack, {true, true});
  const stf::render::Image ideal = stf::render::render(scene, ideal_paths, settings);
  const double paths = double(brute.paths), b = double(brute.collisions) / paths;
  const double c = double(ideal.collisions) / paths, n = double(ideal.strides) / paths;
  std::printf("{\"scene\": \"%s\", \"pack\": \"%s\", \"camera_paths\": %.0f, \"brute_collisions\": %.2f, "
              "\"shell_collisions\": %.2f, \"strides\": %.2f, \"collisions_inside_ideal_strides\": %.2f, "
              "\"speedup_free_strides\": %.2f, \"stride_cost_for_10x\": %.3f, \"bound_at_stride_cost\": {",
              scene_file.c_str(), pack_file.c_str(), paths, b, c, n, double(ideal.ideal_collisions) / paths, b / c,
              (b / 10 - c) / n);
  for (int cost = 2; cost <= 6; ++cost) std::printf("%s\"%d\": %.3f", cost == 2 ? "" : ", ", cost, b / (c + cost * n));
  std::printf("}}\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc >= 4 && std::string(argv[1]) == "--scene") {
    try {
      return scene_bound(argv[2], argv[3], argc > 4 ? std::atoi(argv[4]) : 64, argc > 5 ? std::atol(argv[5]) : 16);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "stride_bound: %s\n", e.what());
      return 2;
    }
  }
  const long paths = argc > 1 ? std::atol(argv[1]) : 20000;
  if (argc == 7 || argc == 8) {
    const stf::Medium m = medium(std::atof(argv[2]), std::atof(argv[3]), std::atof(argv[4]));
    Radii radii{std::atof(argv[5]), std::atof(argv[6])};
    if (argc == 8) {
      radii.r_max = radii.fit(std::atof(argv[7]));  // the ladder's sphere at or below TAU_MAX
      if (radii.r_max <= 0) {
        std::fprintf(stderr, "stride_bound: TAU_MAX %s is below TAU_MIN %s\n", argv[7], argv[5]);
        return 2;
      }
    }
    print_row(m, per_path(m, nullptr, paths).collisions, radii, paths, true);
    std::printf("\n");
    return 0;
  }
  std::printf("[\n");
  bool first = true;
  for (const double tau : {10.0, 30.0, 100.0, 300.0}) {
    const stf::Medium m = medium(tau, 0.999, 0.8);
    const double brute = per_path(m, nullptr, paths).collisions;
    for (const double ratio : {2.0, std::sqrt(2.0), std::sqrt(std::sqrt(2.0)), 1.0})
      for (const double r_min : {1.0, 2.0, 4.0, 8.0}) {
        print_row(m, brute, {r_min, ratio}, paths, first);
        first = false;
      }
  }
  std::printf("\n]\n");
  return 0;
}
