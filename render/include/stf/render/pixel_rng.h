// Random numbers for the renderer: one xoshiro256+ stream per pixel, seeded through
// splitmix64 from (seed, pixel), so an image does not depend on how pixels are shared out.
#pragma once

#include <cstdint>

#include "stf/core/rng.h"  // core/: splitmix64

namespace stf::render {

class PixelRng {
 public:
  PixelRng(std::uint64_t seed, std::uint64_t pixel) {
    std::uint64_t sm = seed ^ (pixel * 0xd1342543de82ef95ull) ^ 0x5851f42d4c957f2dull;
    for (std::uint64_t& s : s_) s = splitmix64(sm);
  }
  // Uniform in [0, 1) with 53 random bits.
  double uniform() { return double(next() >> 11) * 0x1p-53; }
  // Uniform in (0, 1]: safe to take the logarithm of.
  double uniform_open0() { return double((next() >> 11) + 1) * 0x1p-53; }

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  std::uint64_t next() {
    const std::uint64_t result = s_[0] + s_[3];
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }
  std::uint64_t s_[4];
};

}  // namespace stf::render
