#include "stf/render/image_file.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "image_codec.h"
#include "stf/core/plugin.h"

namespace stf::render {

namespace {

constexpr const char* kCodecName = "libstf_image_codec.so";

const ImageCodec* load_codec() {
  const core::PluginPlace place{kCodecName, "STF_IMAGE_CODEC", STF_IMAGE_CODEC_LIBDIR, STF_IMAGE_CODEC_INSTALLED,
                                reinterpret_cast<const void*>(&image_codec)};
  using Export = const ImageCodec* (*)();
  const auto get = reinterpret_cast<Export>(core::plugin_export(
      place, "stf_image_codec",
      std::string("the image codec ") + kCodecName + " (images are read and written through it and OpenImageIO)"));
  return get();
}

double filmic(double x) {
  return std::clamp(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

double srgb(double v) { return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055; }

// The radiance of pixel p, channel c (grey for each of R, G and B).
double value(const Radiance& image, std::size_t p, int c) {
  return image.values[p * std::size_t(image.channels) + std::size_t(image.channels == 3 ? c : 0)];
}

void check_shape(const Radiance& image) {
  if ((image.channels != 1 && image.channels != 3) ||
      image.values.size() != std::size_t(image.width) * std::size_t(image.height) * std::size_t(image.channels))
    throw std::invalid_argument("an image of " + std::to_string(image.values.size()) + " values is not " +
                                std::to_string(image.width) + " x " + std::to_string(image.height) + " pixels of 1 or 3 channels");
}

}  // namespace

const ImageCodec& image_codec() {
  static const ImageCodec* codec = load_codec();  // tried again after a failure (the exception ends the initialisation)
  return *codec;
}

ImageData read_image(const std::string& path) {
  ImageData image;
  image_codec().read(path, image.width, image.height, image.channels, image.values);
  return image;
}

void write_exr(const std::string& path, const Radiance& image) {
  check_shape(image);
  const std::size_t pixels = std::size_t(image.width) * std::size_t(image.height);
  std::vector<float> rgb(pixels * 3);
  for (std::size_t p = 0; p < pixels; ++p)
    for (int c = 0; c < 3; ++c) rgb[p * 3 + std::size_t(c)] = float(value(image, p, c));
  image_codec().write_exr(path, image.width, image.height, rgb);
}

std::vector<std::uint8_t> tone_map(const Radiance& image, double exposure_stops) {
  check_shape(image);
  const double scale = std::exp2(exposure_stops);
  const std::size_t pixels = std::size_t(image.width) * std::size_t(image.height);
  std::vector<std::uint8_t> out(pixels * 3);
  for (std::size_t p = 0; p < pixels; ++p)
    for (int c = 0; c < 3; ++c) {
      const double v = srgb(filmic(std::max(0.0, scale * value(image, p, c))));
      out[p * 3 + std::size_t(c)] = std::uint8_t(std::lround(255 * std::clamp(v, 0.0, 1.0)));
    }
  return out;
}

void write_png(const std::string& path, const Radiance& image, double exposure_stops) {
  image_codec().write_png(path, image.width, image.height, tone_map(image, exposure_stops));
}

}  // namespace stf::render
