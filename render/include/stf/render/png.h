// A minimal PNG writer (8-bit greyscale, uncompressed deflate blocks): no library needed, and
// any viewer reads it.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace stf::render {

// The PNG file's bytes for `grey` [height * width], row 0 at the top.
std::vector<std::uint8_t> encode_png(const std::vector<std::uint8_t>& grey, int width, int height);

// Radiance to 8-bit sRGB: exposure 1 - exp(-L) (the sky, radiance 1, at 63%; the sun
// saturates), then the sRGB transfer curve.
std::vector<std::uint8_t> tone_map(const std::vector<double>& radiance);

}  // namespace stf::render
