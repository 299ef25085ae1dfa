// Random numbers for the walk: xoshiro128+ streams (one per lane, 32-bit state words so
// lanes vectorise), seeded through splitmix64 from (seed, stream id).
#pragma once

#include <cstdint>

namespace stf {

inline std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

struct Xoshiro128State {
  std::uint32_t s[4];
};

// Independent stream for (seed, stream); never the all-zero state.
inline Xoshiro128State seed_stream(std::uint64_t seed, std::uint64_t stream) {
  std::uint64_t sm = seed ^ (stream * 0xd1342543de82ef95ull);
  std::uint64_t a = splitmix64(sm), b = splitmix64(sm);
  Xoshiro128State st{{std::uint32_t(a), std::uint32_t(a >> 32), std::uint32_t(b),
                      std::uint32_t(b >> 32) | 1u}};
  return st;
}

inline std::uint32_t rotl32(std::uint32_t x, int k) { return (x << k) | (x >> (32 - k)); }

// One xoshiro128+ step on state words passed by reference (lets SoA lanes vectorise).
inline std::uint32_t xoshiro128_next(std::uint32_t& s0, std::uint32_t& s1, std::uint32_t& s2,
                                     std::uint32_t& s3) {
  std::uint32_t result = s0 + s3;
  std::uint32_t t = s1 << 9;
  s2 ^= s0;
  s3 ^= s1;
  s1 ^= s2;
  s0 ^= s3;
  s2 ^= t;
  s3 = rotl32(s3, 11);
  return result;
}

// Uniform float in [0, 1) from the top 24 bits (xoshiro128+'s low bits are weak).
inline float uniform01(std::uint32_t bits) { return float(bits >> 8) * 0x1p-24f; }
// Uniform float in (0, 1]: safe to take the logarithm of.
inline float uniform01_open0(std::uint32_t bits) { return float((bits >> 8) + 1) * 0x1p-24f; }

}  // namespace stf
