#include "stf/render/render.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <functional>

#include "stf/core/clock.h"
#include "stf/core/parallel.h"

namespace stf::render {

namespace {

struct PixelResult {
  double mean = 0, variance_of_mean = 0;
};

// One pixel's samples (pixels numbered row by row), jittered over its area, with Welford's
// running mean and variance.
PixelResult render_pixel(const Medium& medium, const Method& method, const ImageSettings& s, std::int64_t pixel,
                         PathCounters& counters, const std::atomic<bool>* cancel) {
  const int px = int(pixel % s.width), py = int(pixel / s.width);
  PixelRng rng(s.seed, std::uint64_t(pixel));
  double mean = 0, m2 = 0;
  for (std::int64_t k = 0; k < s.spp; ++k) {
    if (cancel && cancel->load(std::memory_order_relaxed)) return {};
    const double jx = rng.uniform(), jy = rng.uniform();
    const Ray ray = camera_ray(px + jx, py + jy, s.width, s.height, medium.radius);
    Vec3 entry;
    const double value = enter_sphere(ray, medium.radius, entry) ? method.radiance(entry, ray.direction, rng, counters)
                                                                 : sky_radiance(ray.direction);
    const double delta = value - mean;
    mean += delta / double(k + 1);
    m2 += delta * (value - mean);
  }
  const double n = double(s.spp);
  return {mean, s.spp > 1 ? m2 / (n - 1) / n : 0};
}

}  // namespace

double Image::mean_radiance() const {
  double sum = 0;
  for (double v : mean) sum += v;
  return mean.empty() ? 0 : sum / double(mean.size());
}

Image render(const Medium& medium, const Method& method, const ImageSettings& s) {
  const auto start = std::chrono::steady_clock::now();
  const auto seconds = [&] { return seconds_since(start); };
  Image image;
  image.width = s.width, image.height = s.height;
  const std::int64_t pixels = std::int64_t(s.width) * s.height;
  image.mean.assign(std::size_t(pixels), 0);
  image.variance_of_mean.assign(std::size_t(pixels), 0);
  const RunContext& run = s.run;
  std::vector<PathCounters> counters(std::size_t(run.workers(pixels)));  // one per worker
  std::atomic<std::int64_t> done{0};
  const auto told = [&] { run.tell("", done.load() * s.spp, pixels * s.spp); };
  parallel_for(
      pixels, run,
      [&](std::int64_t p, int worker) {
        const PixelResult r = render_pixel(medium, method, s, p, counters[std::size_t(worker)], run.cancel);
        image.mean[std::size_t(p)] = r.mean;
        image.variance_of_mean[std::size_t(p)] = r.variance_of_mean;
        done.fetch_add(1);
      },
      run.progress ? std::function<void()>(told) : std::function<void()>(), std::chrono::milliseconds(200));
  for (const PathCounters& c : counters) image.collisions += c.collisions, image.strides += c.strides;  // integer sums
  image.paths = done.load() * s.spp;
  image.seconds = seconds();
  if (!run.cancelled()) run.tell("", image.paths, pixels * s.spp);
  return image;
}

}  // namespace stf::render
