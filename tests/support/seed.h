// Reproducible randomness for tests: a fixed default seed that STF_TEST_SEED overrides, so
// any failure can be replayed; tests print it with SCOPED_TRACE.
#pragma once

#include <cstdint>
#include <cstdlib>
#include <string>

namespace stf::test {

inline std::uint64_t test_seed(std::uint64_t fallback) {
  const char* env = std::getenv("STF_TEST_SEED");
  return env ? std::strtoull(env, nullptr, 10) : fallback;
}

inline std::string seed_trace(std::uint64_t seed) {
  return "seed " + std::to_string(seed) + " (replay with STF_TEST_SEED=" + std::to_string(seed) + ")";
}

}  // namespace stf::test
