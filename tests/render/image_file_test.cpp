// EXR and PNG through OpenImageIO: what is written reads back (EXR to float rounding, PNG to the
// byte), the tone curve keeps order and maps black to black, and errors name the path.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <stdexcept>

#include "stf/render/image_file.h"

namespace {

using stf::render::Radiance;
namespace fs = std::filesystem;

std::vector<float> read_back(const std::string& path, int& width, int& height, int& channels,
                             OIIO::TypeDesc type = OIIO::TypeDesc::FLOAT) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw std::runtime_error(OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  width = spec.width, height = spec.height, channels = spec.nchannels;
  std::vector<float> pixels(std::size_t(width) * std::size_t(height) * std::size_t(channels));
  if (type == OIIO::TypeDesc::UINT8) {
    std::vector<unsigned char> bytes(pixels.size());
    in->read_image(0, 0, 0, channels, OIIO::TypeDesc::UINT8, bytes.data());
    for (std::size_t i = 0; i < bytes.size(); ++i) pixels[i] = bytes[i];
  } else {
    in->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, pixels.data());
  }
  return pixels;
}

std::string scratch(const std::string& name) {
  return (fs::temp_directory_path() / ("stf-image-" + std::to_string(::getpid()) + "-" + name)).string();
}

std::vector<double> random_radiance(std::size_t n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::lognormal_distribution<double> radiance(0.0, 2.0);  // from deep shadow to the sun
  std::vector<double> v(n);
  for (double& x : v) x = radiance(rng);
  return v;
}

TEST(ImageFile, ExrReadsBackToFloatRounding) {
  const int w = 7, h = 5;
  for (int channels : {1, 3}) {
    const std::vector<double> v = random_radiance(std::size_t(w * h * channels), 3);
    const std::string path = scratch("rgb.exr");
    stf::render::write_exr(path, Radiance{v, w, h, channels});
    int rw, rh, rc;
    const std::vector<float> back = read_back(path, rw, rh, rc);
    fs::remove(path);
    ASSERT_EQ(rw, w);
    ASSERT_EQ(rh, h);
    ASSERT_EQ(rc, 3);
    for (std::size_t p = 0; p < std::size_t(w * h); ++p)
      for (std::size_t c = 0; c < 3; ++c)
        EXPECT_EQ(back[p * 3 + c], float(v[p * std::size_t(channels) + (channels == 3 ? c : 0)])) << p << " " << c;
  }
}

TEST(ImageFile, PngHoldsTheToneMappedBytes) {
  const int w = 9, h = 4;
  const std::vector<double> v = random_radiance(std::size_t(w * h * 3), 5);
  const std::string path = scratch("rgb.png");
  stf::render::write_png(path, Radiance{v, w, h, 3}, -0.5);
  int rw, rh, rc;
  const std::vector<float> back = read_back(path, rw, rh, rc, OIIO::TypeDesc::UINT8);
  fs::remove(path);
  ASSERT_EQ(rw, w);
  ASSERT_EQ(rh, h);
  ASSERT_EQ(rc, 3);
  const std::vector<std::uint8_t> expected = stf::render::tone_map(Radiance{v, w, h, 3}, -0.5);
  for (std::size_t i = 0; i < expected.size(); ++i) EXPECT_EQ(back[i], float(expected[i])) << i;
}

TEST(ImageFile, ToneCurveKeepsOrderAndExposureScales) {
  std::vector<double> ramp;
  for (int i = 0; i <= 400; ++i) ramp.push_back(i == 0 ? 0.0 : std::pow(10.0, -4 + i * 0.02));  // 1e-4 .. 1e4
  const Radiance grey{ramp, int(ramp.size()), 1, 1};
  const std::vector<std::uint8_t> t = stf::render::tone_map(grey, 0);
  EXPECT_EQ(t[0], 0);
  EXPECT_EQ(t.back(), 255);  // highlights roll off into white, never past it
  for (std::size_t i = 3; i < t.size(); i += 3) EXPECT_GE(t[i], t[i - 3]) << ramp[i / 3];
  // One stop up is twice the radiance.
  std::vector<double> doubled(ramp);
  for (double& x : doubled) x *= 2;
  EXPECT_EQ(stf::render::tone_map(Radiance{doubled, grey.width, 1, 1}, 0), stf::render::tone_map(grey, 1));
  // Grey in, grey out.
  for (std::size_t i = 0; i < t.size(); i += 3) EXPECT_TRUE(t[i] == t[i + 1] && t[i] == t[i + 2]);
}

TEST(ImageFile, ErrorsNameThePathAndShape) {
  const std::vector<double> v(12, 1.0);
  try {
    stf::render::write_exr("/nonexistent-folder/x.exr", Radiance{v, 2, 2, 3});
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-folder/x.exr"), std::string::npos) << e.what();
  }
  EXPECT_THROW(stf::render::write_png(scratch("bad.png"), Radiance{v, 3, 3, 3}, 0), std::invalid_argument);
  EXPECT_FALSE(fs::exists(scratch("bad.png")));
}

}  // namespace
