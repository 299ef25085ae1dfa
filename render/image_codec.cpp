// The image codec module (image_codec.h): OpenImageIO's readers and writers.
#include "image_codec.h"

#include <OpenImageIO/imageio.h>

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

void read_floats(const std::string& path, int& width, int& height, int& channels, std::vector<float>& values) {
  std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::open(path);
  if (!in) throw std::runtime_error(path + ": " + OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  const double count = double(spec.width) * double(spec.height) * double(spec.nchannels);
  if (spec.width < 1 || spec.height < 1 || spec.nchannels < 1 || spec.depth > 1 || count > 1e9)
    throw std::runtime_error(path + ": not a 2D image of at most 1e9 values (" + std::to_string(spec.width) + " x " +
                             std::to_string(spec.height) + " x " + std::to_string(spec.nchannels) + ")");
  values.resize(std::size_t(count));
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, values.data()))
    throw std::runtime_error(path + ": " + in->geterror());
  width = spec.width, height = spec.height, channels = spec.nchannels;
}

void write_rgb_exr(const std::string& path, int width, int height, const std::vector<float>& rgb) {
  OIIO::ImageSpec spec(width, height, 3, OIIO::TypeDesc::FLOAT);
  spec.attribute("compression", "zip");
  spec.attribute("Software", "stf render");
  write_with("openexr", path, spec, rgb);
}

void write_rgb_png(const std::string& path, int width, int height, const std::vector<std::uint8_t>& rgb) {
  OIIO::ImageSpec spec(width, height, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", "sRGB");
  spec.attribute("Software", "stf render");
  write_with("png", path, spec, rgb);
}

const ImageCodec kCodec{read_floats, write_rgb_exr, write_rgb_png};

}  // namespace

}  // namespace stf::render

extern "C" const stf::render::ImageCodec* stf_image_codec() { return &stf::render::kCodec; }
