// The one way stf runs work in parallel: items [0, n) taken in turn from a shared counter by
// worker threads, until done or cancelled. Precompute's chunks, the fit's alpha bins, the render's
// pixels and Python's pieces of arrays all go through it, so threads = 0, cancellation and
// progress mean the same everywhere. Every item's result depends on the item alone (its own
// random stream, its own slot), so results do not depend on the thread count.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <string_view>
#include <system_error>
#include <thread>
#include <type_traits>
#include <vector>

namespace stf {

// Told how far a run is: `done` of `total` units of the step named `step` (the fit's "final
// fit", ...; "" for a run of one step).
using ProgressFn = std::function<void(std::string_view step, std::int64_t done, std::int64_t total)>;

// How a long run runs, apart from what it computes: on how many threads (0: all cores; results
// do not depend on them), what cancels it (Ctrl-C: no further item is started, and the run's
// partial result must be thrown away) and whom it tells of its progress (a worker thread may
// tell, so `progress` must be thread-safe; null: nobody).
struct RunContext {
  int threads = 0;
  const std::atomic<bool>* cancel = nullptr;
  ProgressFn progress;

  bool cancelled() const { return cancel && cancel->load(std::memory_order_relaxed); }
  void tell(std::string_view step, std::int64_t done, std::int64_t total) const {
    if (progress) progress(step, done, total);
  }
  // The workers for n items: the threads asked for (all cores for 0), at most n, at least 1.
  int workers(std::int64_t n) const {
    const int asked = threads > 0 ? threads : int(std::max(1u, std::thread::hardware_concurrency()));
    return int(std::max<std::int64_t>(1, std::min<std::int64_t>(asked, n)));
  }
};

// Runs body(i, worker) for every item i in [0, n), worker in [0, ctx.workers(n)) naming the
// thread (for state kept per worker), until all are done, ctx is cancelled or a body returns
// false (bodies may return void). `tick`, when given, runs on the calling thread every
// `tick_period` while the workers run (progress). Returns true when every item ran. An exception
// a body throws stops the others and is rethrown here once all have stopped.
template <typename Body>
bool parallel_for(std::int64_t n, const RunContext& ctx, Body body, const std::function<void()>& tick = {},
                  std::chrono::milliseconds tick_period = std::chrono::milliseconds(100)) {
  const int workers = ctx.workers(n);
  std::atomic<std::int64_t> next{0};
  std::atomic<bool> stopped{false};
  std::mutex mutex;
  std::condition_variable finished;
  int running = 0;              // guarded by `mutex`
  std::exception_ptr failure;  // the first exception a body threw, guarded by `mutex`
  auto work = [&](int w) {
    try {
      for (std::int64_t i; !stopped.load(std::memory_order_relaxed) && !ctx.cancelled() && (i = next.fetch_add(1)) < n;) {
        if constexpr (std::is_void_v<decltype(body(i, w))>) body(i, w);
        else if (!body(i, w)) stopped = true;
      }
    } catch (...) {  // rethrown on the calling thread once every worker has stopped
      stopped = true;
      std::lock_guard<std::mutex> lock(mutex);
      if (!failure) failure = std::current_exception();
    }
    std::lock_guard<std::mutex> lock(mutex);
    --running;
    finished.notify_one();
  };
  std::vector<std::thread> pool;
  pool.reserve(std::size_t(workers));
  for (int w = 0; w < workers; ++w) {
    std::unique_lock<std::mutex> lock(mutex);
    ++running;
    try {
      pool.emplace_back(work, w);
    } catch (const std::system_error&) {  // no thread to be had: this one works as worker w
      lock.unlock();
      work(w);
      break;
    }
  }
  for (std::unique_lock<std::mutex> lock(mutex); running > 0;)
    if (!finished.wait_for(lock, tick_period, [&] { return running == 0; }) && tick) {
      lock.unlock();
      tick();
      lock.lock();
    }
  for (std::thread& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);
  return !stopped && !ctx.cancelled() && next.load() >= n;
}

}  // namespace stf
