// The parallel, deterministic precompute driver: chunks of paths over worker threads.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>
#include <string>

#include "stf/core/parallel.h"
#include "stf/core/table.h"
#include "stf/precompute/walk.h"

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
  std::int64_t max_scatter = -1;  // -1: no limit but the safety cap
  // One part of the run (a shard, an MPI rank): part `part` of `parts` equal ranges of the
  // run's deterministic chunk stream. The parts of a run sum to exactly the whole run's table.
  int part = 0, parts = 1;
  RunContext run;  // threads, cancel, progress in paths (from the launching thread, every 100 ms)
};

// The run's chunks [first, last) that part `part` of `parts` walks.
struct ChunkRange {
  std::int64_t first = 0, last = 0, count = 0;  // count: chunks of the whole run
};
ChunkRange chunk_range(const PrecomputeSettings& settings);

// A run's state that outlives the process: the chunks of its range already walked (done[c -
// range.first]) and their tally. A checkpoint sink receives a consistent copy at most every
// `seconds`; a run restarted from one walks only what is missing and ends with the same table.
struct Progress {
  std::vector<char> done;
  Tally tally{0, 0};
};
struct Checkpointing {
  const Progress* resume = nullptr;  // start from here (nullptr: from nothing)
  std::function<void(const Progress&)> save;
  double seconds = 30;
};

// Checks a medium and settings; returns a message naming the offending option and what is
// allowed, or nothing when they are valid.
std::optional<std::string> validate(const Medium& medium, const PrecomputeSettings& settings);

// Runs the walk (of the settings' part of the run). Returns nothing when settings.run was
// cancelled before it finished.
std::optional<Table> precompute(const Medium& medium, const PrecomputeSettings& settings,
                                const Checkpointing& checkpointing = {});

}  // namespace stf
