// What a free radius in a mesh costs against a collision, along the points a path visits.
//
//   build/bench/distance_cost [MESH.obj] [SIGMA_T] [POINTS]
//
// The mesh (default data/scenes/meshes/spot.obj) is scaled to a largest side of 1; points come
// from random walks inside it with exponential steps of mean 1 / SIGMA_T (default 1000), in
// walk order, so the caches see what a render's paths show them. Times, per point, the
// distance grid's one-cell bound, its eight-cell bound and Embree's exact query, against a
// collision of the render loop (a flight's logarithm, a Henyey-Greenstein draw, the turn), and
// how far each bound falls short of the exact distance on average. Prints JSON.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "stf/geometry/boundary.h"
#include "stf/geometry/distance_grid.h"
#include "stf/hg.h"
#include "stf/math.h"
#include "stf/render/pixel_rng.h"

namespace {

using namespace stf;

std::vector<Vec3> walk_points(const geometry::Boundary& b, double sigma_t, std::size_t count) {
  render::PixelRng rng(7, 0);
  const geometry::Bounds box = geometry::bounds_of(b.mesh(0));
  std::vector<Vec3> points;
  Vec3 x = box.lower + 0.5 * box.extent();
  while (!b.inside(x, 0)) x = box.lower + Vec3{rng.uniform() * box.extent().x, rng.uniform() * box.extent().y, rng.uniform() * box.extent().z};
  const Vec3 start = x;
  while (points.size() < count) {
    const double c = 2 * rng.uniform() - 1, s = std::sqrt(1 - c * c), phi = 2 * kPi * rng.uniform();
    const Vec3 next = x + (-std::log(rng.uniform_open0()) / sigma_t) * Vec3{s * std::cos(phi), s * std::sin(phi), c};
    x = b.distance(next) > 0 && b.inside(next, 0) ? next : start;
    points.push_back(x);
  }
  return points;
}

template <typename F>
double ns_per_call(std::size_t n, F f) {
  const auto t0 = std::chrono::steady_clock::now();
  double sink = 0;
  for (std::size_t i = 0; i < n; ++i) sink += f(i);
  const double ns = std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count() / double(n);
  if (sink == 1234.5) std::printf(" ");
  return ns;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mesh = argc > 1 ? argv[1] : std::string(STF_SOURCE_DIR) + "/data/scenes/meshes/spot.obj";
  const double sigma_t = argc > 2 ? std::stod(argv[2]) : 1000;
  const std::size_t count = argc > 3 ? std::stoul(argv[3]) : 200000;
  geometry::TriangleMesh m = geometry::oriented_outward(geometry::read_obj(mesh));
  m = geometry::placed(m, 1 / geometry::bounds_of(m).largest_side(), {0, 0, 0});
  const geometry::Boundary boundary({m});
  const auto t0 = std::chrono::steady_clock::now();
  const geometry::DistanceGrid grid(boundary, geometry::bounds_of(m), 256, RunContext{1, nullptr, {}});
  const double build = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::vector<Vec3> p = walk_points(boundary, sigma_t, count);
  std::vector<double> exact(p.size());
  double short_one = 0, short_eight = 0;
  for (std::size_t i = 0; i < p.size(); ++i) exact[i] = boundary.distance(p[i]);
  for (std::size_t i = 0; i < p.size(); ++i)
    short_one += exact[i] - grid.lower_bound(p[i]), short_eight += exact[i] - grid.tight_lower_bound(p[i]);
  render::PixelRng rng(3, 1);
  const HgParams<double> hg = HgParams<double>::make(0.875);
  Vec3 w{0, 0, 1};
  const double collision = ns_per_call(p.size(), [&](std::size_t) {
    const double t = -std::log(rng.uniform_open0()) / sigma_t;
    const CosSin<double> cs = sample_hg(hg, rng.uniform());
    double sp, cp;
    sincos_2pi(rng.uniform(), sp, cp);
    w = Frame::around(w).to_world({cs.sin_theta * cp, cs.sin_theta * sp, cs.cos_theta});
    return t + w.z;
  });
  const double one = ns_per_call(p.size(), [&](std::size_t i) { return grid.lower_bound(p[i]); });
  const double eight = ns_per_call(p.size(), [&](std::size_t i) { return grid.tight_lower_bound(p[i]); });
  const double query = ns_per_call(p.size() / 10, [&](std::size_t i) { return boundary.distance(p[i * 10]); });
  const double mfp = 1 / sigma_t, n = double(p.size());
  std::printf("{\"mesh\": \"%s\", \"sigma_t\": %g, \"points\": %zu, \"grid_bytes\": %zu, \"grid_build_seconds_1_thread\": %.3f,\n"
              " \"ns_per_collision\": %.1f, \"ns_grid_one_cell\": %.1f, \"ns_grid_eight_cells\": %.1f, \"ns_embree_query\": %.1f,\n"
              " \"collisions_per_grid_one_cell\": %.2f, \"collisions_per_grid_eight_cells\": %.2f, \"collisions_per_query\": %.1f,\n"
              " \"mean_shortfall_mfp_one_cell\": %.2f, \"mean_shortfall_mfp_eight_cells\": %.2f}\n",
              mesh.c_str(), sigma_t, p.size(), grid.bytes(), build, collision, one, eight, query, one / collision, eight / collision,
              query / collision, short_one / n / mfp, short_eight / n / mfp);
}
