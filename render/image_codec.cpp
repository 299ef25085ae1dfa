// The image codec module (image_codec.h): OpenImageIO's readers and writers.
#include "image_codec.h"

#include <OpenImageIO/imageio.h>

#include <sys/stat.h>

#include <cerrno>
#include <cmath>
#include <cstring>
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

// A refusal of `path`: why, or OpenImageIO's reason when it gave one.
[[noreturn]] void unreadable(const std::string& path, const std::string& why) {
  throw std::runtime_error(path + ": " + (why.empty() ? "cannot be read (no reason given by OpenImageIO)" : why));
}

// Before any pixel is allocated: the header's size against the file's. An uncompressed format
// (PNM and PFM) needs at least its bits per sample for every value; no compressed one packs more
// than about a thousand values into a byte (deflate's limit), so 2048 per byte (and 1e9 values)
// bound what a file of its size can honestly hold.
void check_size(const std::string& path, const OIIO::ImageInput& in, double file_bytes) {
  const OIIO::ImageSpec& spec = in.spec();
  const double count = double(spec.width) * double(spec.height) * double(spec.nchannels);
  const std::string shape = std::to_string(spec.width) + " x " + std::to_string(spec.height) + " x " + std::to_string(spec.nchannels);
  if (spec.width < 1 || spec.height < 1 || spec.nchannels < 1 || spec.depth > 1 || count > 1e9)
    unreadable(path, "not a 2D image of at most 1e9 values (" + shape + ")");
  const bool raw = std::string(in.format_name()) == "pnm";
  const double bits = spec.get_int_attribute("oiio:BitsPerSample", int(spec.format.size() * 8));
  const double needed = raw ? std::ceil(count * bits / 8) : (count - 1e6) / 2048;
  if (file_bytes < needed)
    unreadable(path, "its header claims " + shape + " values, more than its " + std::to_string(std::int64_t(file_bytes)) +
                         " bytes can hold: truncated or corrupt");
}

void read_floats(const std::string& path, int& width, int& height, int& channels, std::vector<float>& values) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) unreadable(path, std::strerror(errno));
  if (S_ISDIR(st.st_mode)) unreadable(path, "is a folder, not an image file");
  if (!S_ISREG(st.st_mode)) unreadable(path, "not a regular file (a FIFO, socket or device)");
  std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::open(path);
  if (!in) unreadable(path, OIIO::geterror());
  check_size(path, *in, double(st.st_size));
  const OIIO::ImageSpec& spec = in->spec();
  values.resize(std::size_t(spec.width) * std::size_t(spec.height) * std::size_t(spec.nchannels));
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, values.data())) {
    const std::string why = in->geterror();
    unreadable(path, why.empty() ? "its pixels cannot be read: truncated or corrupt" : why);
  }
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
