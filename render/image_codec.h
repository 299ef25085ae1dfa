// The OpenImageIO side of image files, in a module of its own (libstf_image_codec.so) that the
// render library loads the first time an image is read or written. Linked in, OpenImageIO and
// the ~270 shared libraries it brings (video, DICOM, OpenVDB, ...) cost every stf command 0.23 s
// of dynamic linking before it did anything.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace stf::render {

// What the module does; each throws std::runtime_error naming the path.
struct ImageCodec {
  // Any image OpenImageIO reads, as floats [height * width * channels], row 0 at the top.
  void (*read)(const std::string& path, int& width, int& height, int& channels, std::vector<float>& values);
  // RGB float32 OpenEXR, [height * width * 3].
  void (*write_exr)(const std::string& path, int width, int height, const std::vector<float>& rgb);
  // RGB 8-bit PNG, [height * width * 3], marked sRGB.
  void (*write_png)(const std::string& path, int width, int height, const std::vector<std::uint8_t>& rgb);
};

// The module, loaded once: from $STF_IMAGE_CODEC when set (and then only from there), else beside
// the program or library holding the render library (or in the folder above it: the Python
// module's), else where `cmake --install` puts it. Throws std::runtime_error saying which module
// could not be loaded and why.
const ImageCodec& image_codec();

}  // namespace stf::render

// The module's one export.
extern "C" const stf::render::ImageCodec* stf_image_codec();
