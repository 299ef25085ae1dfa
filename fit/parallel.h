// Running independent alpha bins over worker threads.
#pragma once

#include <algorithm>
#include <atomic>
#include <string>
#include <thread>
#include <vector>

#include "stf/fit/fit_settings.h"

namespace stf::fit {

// Set when the user interrupted: for_each_bin skipped bins, so partial results must not be used.
inline bool cancelled(const FitSettings& s) { return s.cancel && s.cancel->load(); }

// Runs f(bin) for every bin over the settings' threads, until cancelled, telling the settings'
// progress of each bin done as part of `step`. Bins are independent, so the result does not
// depend on the thread count.
template <typename F>
void for_each_bin(int bins, const FitSettings& s, const std::string& step, F f) {
  int threads = s.threads > 0 ? s.threads : int(std::max(1u, std::thread::hardware_concurrency()));
  std::atomic<int> next{0}, done{0};
  std::vector<std::thread> pool;
  for (int t = 0; t < std::min(threads, bins); ++t)
    pool.emplace_back([&] {
      for (int b; (b = next.fetch_add(1)) < bins;) {
        if (s.cancel && s.cancel->load(std::memory_order_relaxed)) break;
        f(b);
        if (s.progress) s.progress(step, ++done, bins);
      }
    });
  for (auto& th : pool) th.join();
}

}  // namespace stf::fit
