// Wall-clock seconds for progress lines and the timings files record.
#pragma once

#include <chrono>

namespace stf {

// Seconds from `start` to now, on the steady clock.
inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace stf
