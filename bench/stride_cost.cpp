// What a stride costs, in collisions: the `c` of the bound B / (C + c N) (docs/render.md).
// In one run, on one thread:
//  - per entry of a pack: ns per stride (the entry's StrideForm, and ShellSampler::jump from four
//    uniforms, which draws through it, each from where the last stride left) and ns per collision (one free flight and HG
//    turn in a medium of that entry's albedo and g), and their ratio; the stride form also
//    from four paths in turn (were the processor to overlap strides of different paths, this
//    would be faster per stride);
//  - the floor of a tabulated stride: one alias draw and uniform points, on random tables of
//    256 KiB, 1 MiB and 4 MiB (TableDrawFloor);
//  - inside the render loop: stf render's scene (its medium given by the first entry's albedo
//    and g, sigma_t 100, radius TAU / 100, no shadow rays) with no medium work (a sphere of
//    near vacuum: each path's set-up), brute force and in strides; each run's time less the set-up's, brute force's
//    divided by its collisions, the strided one's less its collisions at that rate divided by
//    its strides.
// JSON on stdout.
//   stride_cost PACK [TAU] [SPP]
#include <stf/pack.h>
#include <stf/sampler.h>
#include <stf/stride.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "stf/render/pixel_rng.h"
#include "stf/render/ladder.h"
#include "stf/render/render.h"
#include "stf/render/scene_geometry.h"
#include "stf/render/sphere_scene.h"

namespace {

using stf::Vec3;
using stf::render::PixelRng;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// ns per jump through the entry's sphere; `sink` keeps the results alive.
double ns_per_stride(const stf::ShellSampler& s, long n, double& sink) {
  PixelRng rng(11, 0);
  Vec3 x{0, 0, 0}, w{0, 0, 1};
  const auto start = Clock::now();
  for (long i = 0; i < n; ++i) {
    const double u0 = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform(), u3 = rng.uniform();
    const stf::WorldExit e = s.jump(x, w, 1.0, u0, u1, u2, u3);
    // The next stride starts where this one left: a chain, as in a renderer.
    x = {e.point.x * 1e-3, e.point.y * 1e-3, e.point.z * 1e-3}, w = e.direction;
  }
  sink += x.x + w.y;
  return 1e9 * seconds_since(start) / double(n);
}

// The same through the entry's stride form (what stf render draws), from `chains` paths in
// turn: with 4, consecutive strides do not wait on each other, so if the processor overlapped
// them a stride would get cheaper.
double ns_per_stride(const stf::StrideForm& s, long n, int chains, double& sink) {
  std::vector<PixelRng> rng;
  for (int k = 0; k < chains; ++k) rng.emplace_back(11, std::uint64_t(k));
  std::vector<Vec3> x(std::size_t(chains), Vec3{0, 0, 0}), w(std::size_t(chains), Vec3{0, 0, 1});
  const auto start = Clock::now();
  for (long i = 0; i < n; i += chains) {
    for (std::size_t k = 0; k < std::size_t(chains); ++k) {
      PixelRng& r = rng[k];
      const stf::Stride e = s.jump(x[k], w[k], 1.0, [&r] { return r.uniform(); });
      x[k] = {e.point.x * 1e-3, e.point.y * 1e-3, e.point.z * 1e-3}, w[k] = e.direction;
    }
  }
  for (std::size_t k = 0; k < std::size_t(chains); ++k) sink += x[k].x + w[k].y;
  return 1e9 * seconds_since(start) / double(n);
}

// a u + b v (the table floor's frame arithmetic, as StrideForm's frames do it)
Vec3 sum(double a, const Vec3& u, double b, const Vec3& v) {
  return {a * u.x + b * v.x, a * u.y + b * v.y, a * u.z + b * v.z};
}

// The least a tabulated stride could cost: one alias draw from a table of `bytes` (8 per
// entry: a float threshold and an index) picks a sub-bin of exit angles and an equal-area cell
// of exit directions about the exit normal; a uniform point of each, turned into the path's
// frame. The table is random (what it draws is not a model): this is the arithmetic and the
// memory traffic of such a draw, not its accuracy (docs/studies/scripts/stride_tables.py measures that).
class TableDrawFloor {
 public:
  TableDrawFloor(std::size_t bytes, std::uint64_t seed) {
    const std::size_t n = (bytes / 8) >> kCellsLog2 << kCellsLog2;
    PixelRng rng(seed, 0);
    for (std::size_t i = 0; i < n; ++i) table_.push_back({float(rng.uniform()), std::uint32_t(rng.uniform() * double(n))});
    const std::size_t subs = n >> kCellsLog2;
    for (std::size_t k = 0; k <= subs; ++k) cos_edge_.push_back(1 - 2 * double(k) / double(subs));
  }
  std::size_t bytes() const { return table_.size() * sizeof(Entry); }
  template <typename Uniform>
  stf::Stride jump(const Vec3& x, const Vec3& dir, Uniform&& uniform) const {
    Vec3 fx, fy;
    stf::orthonormal_basis(dir, fx, fy);
    const double t = uniform() * double(table_.size());
    const std::size_t i = std::size_t(t);
    const std::size_t cell = t - double(i) < table_[i].threshold ? i : table_[i].alias;
    const std::size_t sub = cell >> kCellsLog2, row = (cell >> kColsLog2) & ((1u << kRowsLog2) - 1);
    const double ca = cos_edge_[sub] + uniform() * (cos_edge_[sub + 1] - cos_edge_[sub]);
    const double sa = std::sqrt(std::max(0.0, (1 - ca) * (1 + ca)));
    double sb, cb, sp, cp;
    stf::sincos_2pi(uniform(), sb, cb);
    const double z = 1 - 2 * (double(row) + uniform()) / (1 << kRowsLog2);
    stf::sincos_2pi((double(cell & ((1u << kColsLog2) - 1)) + uniform()) / (1 << kColsLog2), sp, cp);
    const double rho = std::sqrt(std::max(0.0, (1 - z) * (1 + z))), wa = rho * cp;
    const Vec3 local{ca * wa + sa * z, rho * sp, ca * z - sa * wa};  // exit point (sin a, 0, cos a)
    const Vec3 e1 = sum(cb, fx, sb, fy), e2 = sum(cb, fy, -sb, fx);
    const Vec3 p = sum(sa, e1, ca, dir), d = sum(local.x, e1, local.y, e2);
    return {{x.x + p.x, x.y + p.y, x.z + p.z}, {d.x + local.z * dir.x, d.y + local.z * dir.y, d.z + local.z * dir.z},
            stf::kSmooth};
  }

 private:
  static constexpr int kRowsLog2 = 4, kColsLog2 = 5, kCellsLog2 = kRowsLog2 + kColsLog2;
  struct Entry {
    float threshold;
    std::uint32_t alias;
  };
  std::vector<Entry> table_;
  std::vector<double> cos_edge_;
};

double ns_per_table_draw(const TableDrawFloor& s, long n, double& sink) {
  PixelRng rng(11, 0);
  Vec3 x{0, 0, 0}, w{0, 0, 1};
  const auto start = Clock::now();
  for (long i = 0; i < n; ++i) {
    const stf::Stride e = s.jump(x, w, [&rng] { return rng.uniform(); });
    x = {e.point.x * 1e-3, e.point.y * 1e-3, e.point.z * 1e-3}, w = e.direction;
  }
  sink += x.x + w.y;
  return 1e9 * seconds_since(start) / double(n);
}

// ns per collision of a medium of this albedo and g (a sphere too large to leave).
double ns_per_collision(double albedo, double g, long n, double& sink) {
  stf::Medium m;
  m.sigma_s = albedo, m.sigma_a = 1 - albedo, m.g = g, m.radius = 1e9;
  const stf::render::CollisionWalk walk(m);
  PixelRng rng(13, 0);
  Vec3 x{0, 0, 0}, w{0, 0, 1};
  double throughput = 1;
  const auto start = Clock::now();
  for (long i = 0; i < n; ++i) {
    walk.leaves_after_flight(x, w, throughput, rng);
    if (throughput < 1e-200) throughput = 1;
  }
  sink += x.x + throughput;
  return 1e9 * seconds_since(start) / double(n);
}

struct LoopRun {
  double seconds = 0, collisions = 0, strides = 0;
  int spheres = 0;
};

// Every pixel of a 64 x 64 image of stf render's sphere of `m`, `spp` paths each, on one thread,
// by brute force (`pack` null) or in strides, without shadow rays (collisions and strides alone).
LoopRun render_loop(const stf::Medium& m, const std::vector<stf::PackEntry>* pack, int spp) {
  const stf::scene::RenderScene scene = stf::render::sphere_scene(m, 64, 64);
  const stf::render::SceneGeometry geometry(scene, stf::render::FreeRadius::kQuery);
  stf::render::PathOptions options;
  options.next_event = false;
  const stf::render::ScenePaths paths(scene, geometry, pack, options);
  stf::render::ImageSettings s;
  s.width = s.height = 64, s.spp = spp, s.seed = 5, s.run.threads = 1;
  const stf::render::Image image = stf::render::render(scene, paths, s, stf::render::Channels::kOne);
  const stf::SphereLookup* spheres = paths.spheres(0, 0);
  return {image.seconds, double(image.collisions), double(image.strides), spheres ? spheres->size() : 0};
}

// Per entry of the pack: its strides (sampler, stride form, four paths in turn) and collisions.
void print_entries(const std::vector<stf::PackEntry>& pack, double& sink) {
  std::printf("{\"entries\": [\n");
  for (std::size_t i = 0; i < pack.size(); ++i) {
    const stf::StfModel& model = pack[i].model;
    const stf::ShellSampler sampler(model);
    const double sampler_stride = ns_per_stride(sampler, 2'000'000, sink);
    const stf::StrideForm form(model);
    const double stride = ns_per_stride(form, 2'000'000, 1, sink);
    const double interleaved = ns_per_stride(form, 2'000'000, 4, sink);
    const double collision = ns_per_collision(model.albedo, model.g, 10'000'000, sink);
    std::printf(
        "  {\"tau\": %g, \"albedo\": %.6g, \"g\": %g, \"ns_per_stride\": %.1f, "
        "\"ns_per_stride_4_paths_in_turn\": %.1f, \"ns_per_sampler_jump\": %.1f, \"ns_per_collision\": %.1f, "
        "\"stride_cost_collisions\": %.2f}%s\n",
        model.tau, model.albedo, model.g, stride, interleaved, sampler_stride, collision, stride / collision,
        i + 1 < pack.size() ? "," : "");
  }
}

// The tabulated draw's floor at three table sizes, against collisions of the first entry's medium.
void print_table_floor(const stf::StfModel& model, double& sink) {
  std::printf("], \"table_draw_floor\": [\n");
  const double collision = ns_per_collision(model.albedo, model.g, 10'000'000, sink);
  for (const std::size_t bytes : {std::size_t(1) << 18, std::size_t(1) << 20, std::size_t(1) << 22}) {
    const TableDrawFloor table(bytes, 3);
    const double draw = ns_per_table_draw(table, 4'000'000, sink);
    std::printf("  {\"table_bytes\": %zu, \"ns_per_stride\": %.1f, \"ns_per_collision\": %.1f, \"stride_cost_collisions\": %.2f}%s\n",
                table.bytes(), draw, collision, draw / collision, bytes < (std::size_t(1) << 22) ? "," : "");
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: stride_cost PACK [TAU] [SPP]\n");
    return 2;
  }
  std::vector<stf::PackEntry> pack;
  std::string error;
  if (!stf::read_pack_file(argv[1], pack, error) || pack.empty()) {
    std::fprintf(stderr, "stride_cost: %s: %s\n", argv[1],
                 error.empty() ? "no entry" : error.c_str());
    return 2;
  }
  const double tau = argc > 2 ? std::atof(argv[2]) : 100;
  const int spp = argc > 3 ? std::atoi(argv[3]) : 64;
  double sink = 0;
  print_entries(pack, sink);
  print_table_floor(pack.front().model, sink);
  stf::Medium m;
  m.sigma_s = 100 * pack.front().model.albedo, m.sigma_a = 100 - m.sigma_s,
  m.g = pack.front().model.g;
  m.radius = tau / 100;
  stf::Medium vacuum = m;  // camera paths that cross the sphere unscattered: every path's set-up
  vacuum.sigma_s = vacuum.sigma_a = 1e-12;
  const LoopRun o = render_loop(vacuum, nullptr, spp);
  const LoopRun b = render_loop(m, nullptr, spp), s = render_loop(m, &pack, spp);
  const double ns_collision = 1e9 * (b.seconds - o.seconds) / b.collisions;
  const double ns_stride =
      s.strides > 0 ? (1e9 * (s.seconds - o.seconds) - ns_collision * s.collisions) / s.strides : 0;
  std::printf(
      "], \"render_loop\": {\"tau\": %g, \"spheres\": %d, \"spp\": %d, \"set_up_seconds\": %.3f, \"brute_seconds\": %.3f, "
      "\"brute_collisions\": %.0f, \"stf_seconds\": %.3f, \"stf_collisions\": %.0f, "
      "\"stf_strides\": %.0f, "
      "\"ns_per_collision\": %.1f, \"ns_per_stride\": %.1f, \"stride_cost_collisions\": %.2f, "
      "\"brute_over_stf\": %.3f}, "
      "\"sink\": %g}\n",
      tau, s.spheres, spp, o.seconds, b.seconds, b.collisions, s.seconds, s.collisions, s.strides,
      ns_collision, ns_stride, ns_stride / ns_collision, b.seconds / s.seconds, sink);
  return 0;
}
