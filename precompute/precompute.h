// The parallel, deterministic precompute driver: chunks of paths over worker threads.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "table.h"

namespace stf {

// Largest optical radius a table may have (tau = (sigma_s + sigma_a) * radius).
inline constexpr double kMaxTau = 1e7;

// Largest table stf holds in memory: with the grid it needs about
// cells * (16 * alpha_bins + 40) bytes (two half-tables of float64 counts, cell centres and
// solid angles), and fitting it needs more again. Checked before any work.
inline constexpr double kMaxTableBytes = 8.0 * (1 << 30);
double table_bytes(std::int64_t cells, int alpha_bins);

struct PrecomputeSettings {
  int alpha_bins = 90;
  std::string grid = "healpix:16";
  std::int64_t paths = 1'000'000;
  std::int64_t seed = 1;
  int threads = 0;                // 0: all cores
  std::int64_t max_scatter = -1;  // -1: no limit but the safety cap
};

// Called from the launching thread about every 100 ms with the paths finished so far.
using ProgressFn = std::function<void(std::int64_t done, std::int64_t total, double seconds)>;

// Checks a medium and settings; returns a message naming the offending option and what is
// allowed, or nothing when they are valid.
std::optional<std::string> validate(const Medium& medium, const PrecomputeSettings& settings);

// Runs the walk. Returns nothing when `cancel` was set before it finished.
std::optional<Table> precompute(const Medium& medium, const PrecomputeSettings& settings,
                                const std::atomic<bool>* cancel = nullptr,
                                const ProgressFn& progress = {});

}  // namespace stf
