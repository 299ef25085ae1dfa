#include "stf/render/render.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>

#include "stf/core/clock.h"
#include "stf/core/parallel.h"

namespace stf::render {

namespace {

// Welford's running mean and variance of one pixel's samples of one channel.
struct Running {
  double mean = 0, m2 = 0;
  std::int64_t n = 0;
  void add(double value) {
    const double delta = value - mean;
    mean += delta / double(++n);
    m2 += delta * (value - mean);
  }
  double variance_of_mean() const { return n > 1 ? m2 / double(n - 1) / double(n) : 0; }
};

// Every pixel (numbered row by row) over the run's threads: `pixel(p, rng, counters, sums)`
// fills the pixel's running sums per channel; the image takes their means and variances.
template <typename Pixel>
Image render_pixels(const ImageSettings& s, int channels, Pixel pixel) {
  const auto start = std::chrono::steady_clock::now();
  Image image;
  image.width = s.width, image.height = s.height, image.channels = channels;
  const std::int64_t pixels = std::int64_t(s.width) * s.height;
  image.mean.assign(std::size_t(pixels * channels), 0);
  image.variance_of_mean.assign(std::size_t(pixels * channels), 0);
  const RunContext& run = s.run;
  std::vector<PathCounters> counters(std::size_t(run.workers(pixels)));  // one per worker
  std::atomic<std::int64_t> done{0};
  const auto told = [&] { run.tell("", done.load() * s.spp, pixels * s.spp); };
  parallel_for(
      pixels, run,
      [&](std::int64_t p, int worker) {
        PixelRng rng(s.seed, std::uint64_t(p));
        Running sums[3];
        if (!pixel(p, rng, counters[std::size_t(worker)], sums)) return;
        for (int c = 0; c < channels; ++c) {
          image.mean[std::size_t(p * channels + c)] = sums[c].mean;
          image.variance_of_mean[std::size_t(p * channels + c)] = sums[c].variance_of_mean();
        }
        done.fetch_add(1);
      },
      run.progress ? std::function<void()>(told) : std::function<void()>(), std::chrono::milliseconds(200));
  for (const PathCounters& c : counters) {  // integer sums
    image.collisions += c.collisions, image.null_collisions += c.null_collisions, image.strides += c.strides, image.distance_queries += c.distance_queries;
    image.shadow_rays += c.shadow_rays, image.rays += c.rays, image.ideal_collisions += c.ideal_collisions;
    image.once_scattered_exits += c.once_scattered_exits;
    for (int k = 0; k < kRayKinds; ++k) image.rays_by[k] += c.rays_by[k];
  }
  image.paths = done.load() * s.spp;
  image.seconds = seconds_since(start);
  if (!run.cancelled()) run.tell("", image.paths, pixels * s.spp);
  return image;
}

}  // namespace

PinholeCamera::PinholeCamera(const scene::CameraSpec& cam, int width, int height)
    : origin_(cam.position), forward_(normalize(cam.look_at - cam.position)), half_(std::tan(cam.fov * kPi / 360)),
      width_(width), height_(height) {
  right_ = normalize(cross(forward_, cam.up)), up_ = cross(right_, forward_);
}

Ray camera_ray(const scene::CameraSpec& cam, double px, double py, int width, int height) {
  return PinholeCamera(cam, width, height).ray(px, py);
}

double Image::mean_radiance(int channel) const {
  double sum = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < mean.size(); ++i)
    if (channel < 0 || int(i % std::size_t(channels)) == channel) sum += mean[i], ++n;
  return n == 0 ? 0 : sum / double(n);
}

Image render(const scene::RenderScene& scene, const ScenePaths& paths, const ImageSettings& s, Channels channels) {
  const int n = channels == Channels::kRgb ? 3 : 1;
  const PinholeCamera camera(scene.camera, s.width, s.height);
  return render_pixels(s, n, [&](std::int64_t p, PixelRng& rng, PathCounters& counters, Running* sums) {
    const int px = int(p % s.width), py = int(p / s.width);
    for (std::int64_t k = 0; k < s.spp; ++k) {
      if (s.run.cancelled()) return false;
      const double jx = rng.uniform(), jy = rng.uniform();
      const Ray ray = camera.ray(px + jx, py + jy);
      const int c = int(k % n);
      sums[c].add(paths.radiance(ray.origin, ray.direction, c, rng, counters));
    }
    return true;
  });
}

}  // namespace stf::render
