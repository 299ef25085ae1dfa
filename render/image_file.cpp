#include "stf/render/image_file.h"

#include <dlfcn.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <stdexcept>

#include "image_codec.h"

namespace stf::render {

namespace {

constexpr const char* kCodecName = "libstf_image_codec.so";

std::string folder_of(const std::string& path) {
  const std::size_t slash = path.rfind('/');
  return slash == std::string::npos ? "." : path.substr(0, slash);
}

// Where the codec may be: $STF_IMAGE_CODEC alone when set; else beside the file that holds this
// code (the stf program, or the Python module, whose folder's parent holds it in a build tree),
// beside the running program or in the library folder of its install prefix, and where
// `cmake --install` puts it by default.
std::vector<std::string> codec_candidates() {
  if (const char* given = std::getenv("STF_IMAGE_CODEC")) return {given};
  std::vector<std::string> where;
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&image_codec), &info) && info.dli_fname && std::string(info.dli_fname).find('/') != std::string::npos) {
    where.push_back(folder_of(info.dli_fname) + "/" + kCodecName);
    where.push_back(folder_of(info.dli_fname) + "/../" + kCodecName);
  }
  char exe[4096];
  const ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
  if (n > 0) {
    const std::string program = folder_of(std::string(exe, std::size_t(n)));
    where.push_back(program + "/" + kCodecName);
    where.push_back(program + "/../" STF_IMAGE_CODEC_LIBDIR "/stf/" + kCodecName);  // an installed stf
  }
  where.push_back(STF_IMAGE_CODEC_INSTALLED);
  return where;
}

const ImageCodec* load_codec() {
  std::string why;
  for (const std::string& path : codec_candidates()) {
    if (void* module = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) {
      using Export = const ImageCodec* (*)();
      if (auto get = reinterpret_cast<Export>(dlsym(module, "stf_image_codec"))) return get();
      why = path + " has no stf_image_codec";
      continue;
    }
    if (why.empty()) why = dlerror();
  }
  throw std::runtime_error(std::string("cannot load the image codec ") + kCodecName +
                           " (images are read and written through it and OpenImageIO): " + why);
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
