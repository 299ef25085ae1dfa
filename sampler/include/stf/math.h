// Small numerical kernels of the sampler.
#pragma once

#include <cstdint>
#include <cstring>

namespace stf {

// sin and cos of 2 pi u for u in [0, 1], to double precision, without libm: the quadrant
// q = round(4u) is exact in u, and on the remainder a = (4u - q) pi / 2 in [-pi/4, pi/4] the
// Taylor series to a^17 / a^18 are below 1e-18 off.
inline void sincos_2pi(double u, double& s, double& c) {
  double t = 4 * u;
  int q = int(t + 0.5);
  double a = (t - q) * 1.5707963267948966;
  double a2 = a * a;
  double sp = 1.0 / 355687428096000.0;  // 1 / 17!
  sp = sp * -a2 + 1.0 / 1307674368000.0;
  sp = sp * -a2 + 1.0 / 6227020800.0;
  sp = sp * -a2 + 1.0 / 39916800.0;
  sp = sp * -a2 + 1.0 / 362880.0;
  sp = sp * -a2 + 1.0 / 5040.0;
  sp = sp * -a2 + 1.0 / 120.0;
  sp = sp * -a2 + 1.0 / 6.0;
  double sa = a - a * a2 * sp;
  double cp = 1.0 / 6402373705728000.0;  // 1 / 18!
  cp = cp * -a2 + 1.0 / 20922789888000.0;
  cp = cp * -a2 + 1.0 / 87178291200.0;
  cp = cp * -a2 + 1.0 / 479001600.0;
  cp = cp * -a2 + 1.0 / 3628800.0;
  cp = cp * -a2 + 1.0 / 40320.0;
  cp = cp * -a2 + 1.0 / 720.0;
  cp = cp * -a2 + 1.0 / 24.0;
  cp = cp * -a2 + 0.5;
  double ca = 1 - a2 * cp;
  // The quadrant q mod 4 swaps and negates: (sa, ca), (ca, -sa), (-sa, -ca), (-ca, sa). Selected
  // by index and sign factor, as a branch on a uniform's quadrant mispredicts half the time.
  const double both[2] = {sa, ca};
  s = both[q & 1] * double(1 - (q & 2));
  c = both[(q & 1) ^ 1] * double(1 - ((q + 1) & 2));
}

// Uniforms for the retries of a rejection sampler: SplitMix64 seeded from the bits of the first
// try's numbers, so a draw stays a deterministic function of its inputs.
class RetryStream {
 public:
  RetryStream(double u0, double u1, double u2, double u3) {
    for (double u : {u0, u1, u2, u3}) {
      std::uint64_t bits;
      std::memcpy(&bits, &u, sizeof bits);
      state_ = state_ * 0x9E3779B97F4A7C15ull + bits;
      next();
    }
  }
  double uniform() { return double(next() >> 11) * 0x1.0p-53; }

 private:
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  std::uint64_t state_ = 0x243F6A8885A308D3ull;
};

}  // namespace stf
