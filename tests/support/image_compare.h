// Two renders of one scene compared as the render targets state them: per channel, blocks of
// pixels whose mean difference is within a number of sigma of their combined variance, and the
// whole image's mean per channel.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

struct ImageComparison {
  double max_block_z = 0;          // over blocks with any variance
  int blocks = 0;                  // blocks compared
  int identical_blocks = 0;        // blocks without variance in either (sky only): equal means
  std::vector<double> mean_ratio;  // per channel: mean of b over mean of a
  std::vector<double> mean_z;      // per channel: difference of the means in sigma
};

// Images [height * width * channels] with their variances of the mean, in blocks of
// `block` x `block` pixels.
inline ImageComparison compare_images(const std::vector<double>& mean_a, const std::vector<double>& var_a,
                                      const std::vector<double>& mean_b, const std::vector<double>& var_b, int height,
                                      int width, int channels, int block) {
  ImageComparison r;
  for (int c = 0; c < channels; ++c) {
    double sum_a = 0, sum_b = 0, var = 0;
    for (int by = 0; by + block <= height; by += block)
      for (int bx = 0; bx + block <= width; bx += block) {
        double diff = 0, v = 0;
        for (int y = by; y < by + block; ++y)
          for (int x = bx; x < bx + block; ++x) {
            const std::size_t i = std::size_t((y * width + x) * channels + c);
            diff += mean_b[i] - mean_a[i], v += var_a[i] + var_b[i];
          }
        if (v == 0) {
          r.identical_blocks += diff == 0;
          continue;
        }
        ++r.blocks;
        r.max_block_z = std::max(r.max_block_z, std::abs(diff) / std::sqrt(v));
      }
    for (std::size_t i = std::size_t(c); i < mean_a.size(); i += std::size_t(channels))
      sum_a += mean_a[i], sum_b += mean_b[i], var += var_a[i] + var_b[i];
    r.mean_ratio.push_back(sum_b / sum_a);
    r.mean_z.push_back(var > 0 ? (sum_b - sum_a) / std::sqrt(var) : 0);
  }
  return r;
}
