// Rendering the scene of scene.h with one of the methods of tracer.h: every pixel's samples
// come from the pixel's own random stream, so the image is the same for any thread count.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <vector>

#include "stf/core/parallel.h"
#include "stf/render/render_scene.h"
#include "stf/render/tracer.h"

namespace stf::render {

struct ImageSettings {
  int width = 64, height = 64;
  std::int64_t spp = 16;  // samples (camera paths) per pixel
  std::uint64_t seed = 1;
  RunContext run;  // threads, cancel (then the image is incomplete), progress in paths
};

struct Image {
  int width = 0, height = 0;
  std::vector<double> mean;              // [height * width], row 0 at the top
  std::vector<double> variance_of_mean;  // sample variance / spp, per pixel
  double seconds = 0;                    // wall clock
  std::int64_t paths = 0, collisions = 0, strides = 0;
  double mean_radiance() const;
};

// Renders until done or settings.run is cancelled (then the image is incomplete: check the
// flag), telling its progress in paths five times a second.
Image render(const Medium& medium, const Method& method, const ImageSettings& settings);

}  // namespace stf::render
