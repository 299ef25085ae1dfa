#include "stf/render/environment.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "stf/render/image_file.h"

namespace stf::render {

EnvironmentMap::EnvironmentMap(int width, int height, std::vector<float> rgb)
    : width_(width), height_(height), rgb_(std::move(rgb)) {
  if (width < 1 || height < 1 || rgb_.size() != std::size_t(width) * std::size_t(height) * 3)
    throw std::invalid_argument("an environment map needs width x height x 3 values");
  for (std::size_t i = 0; i < rgb_.size(); ++i)
    if (!(rgb_[i] >= 0) || !std::isfinite(rgb_[i]))
      throw std::invalid_argument("pixel (" + std::to_string(i / 3 % std::size_t(width)) + ", " +
                                  std::to_string(i / 3 / std::size_t(width)) + ") is " + std::to_string(rgb_[i]) +
                                  ": radiance must be finite and >= 0");
  std::vector<double> weight(std::size_t(width) * std::size_t(height));
  double total = 0;
  for (int v = 0; v < height; ++v) {
    const double sin_theta = std::sin(kPi * (v + 0.5) / height);
    for (int u = 0; u < width; ++u) {
      const std::size_t t = std::size_t(v) * std::size_t(width) + std::size_t(u);
      total += weight[t] = sin_theta * (double(rgb_[3 * t]) + rgb_[3 * t + 1] + rgb_[3 * t + 2]) / 3;
    }
  }
  probability_.assign(weight.size(), 0.0);
  if (!(total > 0)) return;
  for (std::size_t t = 0; t < weight.size(); ++t) probability_[t] = weight[t] / total;
  texels_ = AliasTable(weight);
}

EnvironmentMap EnvironmentMap::from_file(const std::string& path, double scale) {
  const ImageData image = read_image(path);
  std::vector<float> rgb;
  rgb.reserve(std::size_t(image.width) * std::size_t(image.height) * 3);
  for (std::size_t p = 0; p < std::size_t(image.width) * std::size_t(image.height); ++p)
    for (int c = 0; c < 3; ++c)
      rgb.push_back(float(scale * image.values[p * std::size_t(image.channels) + std::size_t(image.channels >= 3 ? c : 0)]));
  try {
    return EnvironmentMap(image.width, image.height, std::move(rgb));
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
}

double EnvironmentMap::density(std::size_t texel, double sin_theta) const {
  const double p = probability_[texel];
  return p > 0 && sin_theta > 0 ? p * width_ * height_ / (2 * kPi * kPi * sin_theta) : 0.0;
}

std::size_t EnvironmentMap::texel(const Vec3& d, double& sin_theta) const {
  // The polar angle by atan2, which keeps its digits near the poles (acos of d.y would not).
  sin_theta = std::hypot(d.x, d.z);
  const double theta = std::atan2(sin_theta, d.y), phi = std::atan2(d.x, -d.z);
  const int v = std::min(height_ - 1, int(theta / kPi * height_));
  const int u = std::clamp(int((phi + kPi) / (2 * kPi) * width_), 0, width_ - 1);
  return std::size_t(v) * std::size_t(width_) + std::size_t(u);
}

double EnvironmentMap::radiance(const Vec3& direction, int channel) const {
  double sin_theta;
  return rgb_[3 * texel(direction, sin_theta) + std::size_t(channel)];
}

double EnvironmentMap::pdf(const Vec3& direction) const {
  double sin_theta;
  const std::size_t t = texel(direction, sin_theta);
  return density(t, sin_theta);
}

Vec3 EnvironmentMap::sample(double u1, double u2, double& pdf) const {
  pdf = 0;
  if (texels_.size() == 0) return {0, 1, 0};
  double in_texel;
  const int t = texels_.sample(u1, in_texel);
  const int v = t / width_, u = t % width_;
  const double theta = kPi * (v + u2) / height_, phi = 2 * kPi * (u + in_texel) / width_ - kPi;
  const double sin_theta = std::sin(theta);
  pdf = density(std::size_t(t), sin_theta);
  return {sin_theta * std::sin(phi), std::cos(theta), -sin_theta * std::cos(phi)};
}

}  // namespace stf::render
