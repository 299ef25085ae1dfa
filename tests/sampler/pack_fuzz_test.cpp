// Fuzzed packs, built with AddressSanitizer and UndefinedBehaviorSanitizer: random payload
// bytes (with the checksum recomputed, so the parser itself is exercised), random lengths and
// random headers must give an error or a valid model, never a crash or undefined behaviour.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "stf/core/rng.h"
#include "stf/pack.h"
#include "stf/sampler.h"
#include "test_models.h"

namespace stf {
namespace {

std::uint64_t fnv1a(const std::uint8_t* p, std::size_t n) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (std::size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 0x100000001b3ull;
  return h;
}

void fix_checksum(std::vector<std::uint8_t>& pack) {
  if (pack.size() < 32) return;
  std::uint64_t h = fnv1a(pack.data() + 32, pack.size() - 32);
  std::memcpy(pack.data() + 24, &h, 8);
}

TEST(PackFuzz, MutatedPacksFailCleanlyOrLoad) {
  const std::vector<std::vector<std::uint8_t>> seeds = {write_pack({{"a", test::make_vmf_model()}}),
                                                        write_pack({{"b", test::make_sh_model()}})};
  std::uint64_t s = 71;
  int loaded = 0, rejected = 0;
  for (int round = 0; round < 3000; ++round) {
    std::vector<std::uint8_t> p = seeds[round % 2];
    int flips = 1 + int(splitmix64(s) % 8);
    for (int f = 0; f < flips; ++f) p[splitmix64(s) % p.size()] = std::uint8_t(splitmix64(s));
    if (round % 3 == 0) p.resize(splitmix64(s) % (p.size() + 1));
    if (round % 5 != 0) fix_checksum(p);
    std::vector<PackEntry> out;
    std::string error;
    if (read_pack(p.data(), p.size(), out, error)) {
      ++loaded;
      for (const PackEntry& e : out) {  // a pack that loads must sample finitely
        ShellSampler sampler(e.model);
        ExitSample x = sampler.sample(0.3, 0.6, 0.2, 0.9);
        EXPECT_TRUE(std::isfinite(x.pdf));
      }
    } else {
      ++rejected;
      EXPECT_FALSE(error.empty());
    }
  }
  EXPECT_GT(rejected, 0);
}

}  // namespace
}  // namespace stf
