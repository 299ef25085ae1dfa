// Rendering the scene of scene.h with one of the methods of tracer.h: every pixel's samples
// come from the pixel's own random stream, so the image is the same for any thread count.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <vector>

#include "stf/render/render_scene.h"
#include "stf/render/tracer.h"

namespace stf::render {

struct ImageSettings {
  int width = 64, height = 64;
  std::int64_t spp = 16;  // samples (camera paths) per pixel
  std::uint64_t seed = 1;
  int threads = 0;  // 0: all cores
};

struct Image {
  int width = 0, height = 0;
  std::vector<double> mean;              // [height * width], row 0 at the top
  std::vector<double> variance_of_mean;  // sample variance / spp, per pixel
  double seconds = 0;                    // wall clock
  std::int64_t paths = 0, collisions = 0, strides = 0;
  double mean_radiance() const;
};

// (paths done, paths in all, seconds so far): called from one worker thread at a time, at
// most five times a second.
using RenderProgress = std::function<void(std::int64_t, std::int64_t, double)>;

// Renders until done or `cancel` is set (then the image is incomplete: check the flag).
Image render(const Medium& medium, const Method& method, const ImageSettings& settings,
             const RenderProgress& progress = {}, const std::atomic<bool>* cancel = nullptr);

}  // namespace stf::render
