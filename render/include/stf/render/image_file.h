// Images people look at and tools read, through OpenImageIO: linear OpenEXR for tools and
// tone-mapped 8-bit sRGB PNG for eyes.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace stf::render {

// Linear radiance, [height * width * channels] (1 channel: grey; 3: RGB), row 0 at the top.
struct Radiance {
  const std::vector<double>& values;
  int width = 0, height = 0, channels = 1;
};

// An image as read: [height * width * channels] floats, row 0 at the top.
struct ImageData {
  int width = 0, height = 0, channels = 0;
  std::vector<float> values;
};

// Reads any image OpenImageIO reads (OpenEXR, Radiance HDR, PNG, ...) as floats; throws
// std::runtime_error naming the path and OpenImageIO's reason.
ImageData read_image(const std::string& path);

// Writes `image` as RGB float32 OpenEXR (grey written to all three channels) to `path`, in the
// OpenEXR format whatever the path's name; throws std::runtime_error naming the path.
void write_exr(const std::string& path, const Radiance& image);

// Writes `image` as 8-bit sRGB PNG after tone_map(); throws std::runtime_error naming the path.
void write_png(const std::string& path, const Radiance& image, double exposure_stops);

// Radiance to 8-bit sRGB, RGB [height * width * 3]: times 2^exposure_stops, then a filmic curve
// (Narkowicz's fit of the ACES reference tone scale: a toe, a shoulder that rolls highlights off
// instead of clipping them, radiance 1 at 0.80 before the sRGB curve), then the sRGB transfer
// curve.
std::vector<std::uint8_t> tone_map(const Radiance& image, double exposure_stops);

}  // namespace stf::render
