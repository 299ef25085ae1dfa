// Running independent alpha bins over worker threads.
#pragma once

#include <atomic>
#include <string>

#include "stf/core/parallel.h"
#include "stf/fit/fit_settings.h"

namespace stf::fit {

// Set when the user interrupted: for_each_bin skipped bins, so partial results must not be used.
inline bool cancelled(const FitSettings& s) { return s.run.cancelled(); }

// Runs f(bin) for every bin over the settings' threads (stf/core/parallel.h), until cancelled,
// telling the settings' progress of each bin done as part of `step`. Bins are independent, so
// the result does not depend on the thread count.
template <typename F>
void for_each_bin(int bins, const FitSettings& s, const std::string& step, F f) {
  std::atomic<int> done{0};
  parallel_for(bins, s.run, [&](std::int64_t b, int) {
    f(int(b));
    s.run.tell(step, ++done, bins);
  });
}

}  // namespace stf::fit
