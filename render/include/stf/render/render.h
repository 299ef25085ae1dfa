// Rendering a scene through its camera paths (scene_paths.h), brute force or strided: every
// pixel's samples come from the pixel's own random stream, so the image is the same for any
// thread count.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <vector>

#include "stf/core/parallel.h"
#include "stf/render/scene_paths.h"

namespace stf::render {

struct ImageSettings {
  int width = 64, height = 64;
  std::int64_t spp = 16;  // samples (camera paths) per pixel
  std::uint64_t seed = 1;
  RunContext run;  // threads, cancel (then the image is incomplete), progress in paths
};

struct Image {
  int width = 0, height = 0, channels = 1;
  std::vector<double> mean;              // [height * width * channels], row 0 at the top
  std::vector<double> variance_of_mean;  // sample variance / samples, per pixel and channel
  double seconds = 0;                    // wall clock
  std::int64_t paths = 0, collisions = 0, null_collisions = 0, strides = 0, distance_queries = 0, shadow_rays = 0, rays = 0, ideal_collisions = 0,
               once_scattered_exits = 0;
  std::int64_t rays_by[kRayKinds] = {};
  double mean_radiance(int channel = -1) const;  // over one channel, or all (-1)
};

struct Ray {
  Vec3 origin, direction;
};
// A pinhole camera's frame, built once per image: its rays through image positions.
class PinholeCamera {
 public:
  PinholeCamera(const scene::CameraSpec& camera, int width, int height);
  // The ray through image position (px, py) in pixels (x right, y down, (0, 0) the top-left corner).
  Ray ray(double px, double py) const {
    const double sx = (2 * px / width_ - 1) * half_ * width_ / height_, sy = (1 - 2 * py / height_) * half_;
    return {origin_, normalize(forward_ + sx * right_ + sy * up_)};
  }

 private:
  Vec3 origin_, forward_, right_, up_;
  double half_;
  int width_, height_;
};

// The camera ray through image position (px, py) of a width x height image (one ray; a render
// builds its PinholeCamera once).
Ray camera_ray(const scene::CameraSpec& camera, double px, double py, int width, int height);

// How many channels an image carries: RGB (samples k, k + 3, ... of a pixel carry channel k), or
// one (every sample carries channel 0: a scene whose media are the same in every channel).
enum class Channels { kRgb, kOne };

// Renders a scene's image (settings' width and height; the camera's field of view and pose from
// the scene) through `paths` (brute force or strides) until done or settings.run is cancelled
// (then the image is incomplete: check the flag), telling its progress in paths five times a
// second.
Image render(const scene::RenderScene& scene, const ScenePaths& paths, const ImageSettings& settings,
             Channels channels = Channels::kRgb);

}  // namespace stf::render
