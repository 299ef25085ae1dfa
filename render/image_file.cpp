#include "stf/render/image_file.h"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>

namespace stf::render {

namespace {

// Opens `path` for writing in `format` ("openexr", "png"), writes `pixels` and closes it;
// OpenImageIO's error, naming the path, on any failure.
template <typename T>
void write_with(const std::string& format, const std::string& path, const OIIO::ImageSpec& spec,
                const std::vector<T>& pixels) {
  std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(format);
  if (!out) throw std::runtime_error(path + ": no " + format + " writer: " + OIIO::geterror());
  const bool written = out->open(path, spec) && out->write_image(spec.format, pixels.data()) && out->close();
  if (!written) throw std::runtime_error(path + ": " + out->geterror());
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

ImageData read_image(const std::string& path) {
  std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::open(path);
  if (!in) throw std::runtime_error(path + ": " + OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  ImageData image{spec.width, spec.height, spec.nchannels, {}};
  const double count = double(spec.width) * double(spec.height) * double(spec.nchannels);
  if (spec.width < 1 || spec.height < 1 || spec.nchannels < 1 || spec.depth > 1 || count > 1e9)
    throw std::runtime_error(path + ": not a 2D image of at most 1e9 values (" + std::to_string(spec.width) + " x " +
                             std::to_string(spec.height) + " x " + std::to_string(spec.nchannels) + ")");
  image.values.resize(std::size_t(count));
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, image.values.data()))
    throw std::runtime_error(path + ": " + in->geterror());
  return image;
}

void write_exr(const std::string& path, const Radiance& image) {
  check_shape(image);
  const std::size_t pixels = std::size_t(image.width) * std::size_t(image.height);
  std::vector<float> rgb(pixels * 3);
  for (std::size_t p = 0; p < pixels; ++p)
    for (int c = 0; c < 3; ++c) rgb[p * 3 + std::size_t(c)] = float(value(image, p, c));
  OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::FLOAT);
  spec.attribute("compression", "zip");
  spec.attribute("Software", "stf render");
  write_with("openexr", path, spec, rgb);
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
  OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", "sRGB");
  spec.attribute("Software", "stf render");
  write_with("png", path, spec, tone_map(image, exposure_stops));
}

}  // namespace stf::render
