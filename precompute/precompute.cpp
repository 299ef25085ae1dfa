#include "stf/precompute/precompute.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <vector>

#include "stf/core/clock.h"
#include "stf/core/grid.h"
#include "stf/core/minimal_table.h"
#include "stf/core/parallel.h"
#include "stf/precompute/walk.h"

namespace stf {

std::optional<std::string> validate(const Medium& m, const PrecomputeSettings& s) {
  if (!(std::isfinite(m.sigma_s) && m.sigma_s >= 0))
    return "--sigma-s must be a finite number >= 0, got " + fmt::format("{:g}", m.sigma_s);
  if (!(std::isfinite(m.sigma_a) && m.sigma_a >= 0))
    return "--sigma-a must be a finite number >= 0, got " + fmt::format("{:g}", m.sigma_a);
  if (!(m.g > -1 && m.g < 1)) return "--g must be in (-1, 1), got " + fmt::format("{:g}", m.g);
  if (!(std::isfinite(m.radius) && m.radius > 0))
    return "--radius must be a finite number > 0, got " + fmt::format("{:g}", m.radius);
  if (!(m.sigma_t() > 0))
    return "--sigma-s and --sigma-a must not both be 0 (a vacuum has no table)";
  if (!(std::isfinite(m.tau()) && m.tau() <= kMaxTau))
    return "--radius times (--sigma-s + --sigma-a) must be at most " + fmt::format("{:g}", kMaxTau) + ", got " + fmt::format("{:g}", m.tau());
  if (s.alpha_bins < 1 || s.alpha_bins > kMaxAlphaBins)
    return "--alpha-bins must be in 1.." + std::to_string(kMaxAlphaBins) + ", got " + std::to_string(s.alpha_bins);
  if (s.paths < 1) return "--paths must be at least 1, got " + std::to_string(s.paths);
  if (s.parts < 1 || s.part < 0 || s.part >= s.parts)
    return "--shard K/N needs 0 <= K < N, got " + std::to_string(s.part) + "/" + std::to_string(s.parts);
  if (const ChunkRange r = chunk_range(s); s.parts > 1 && r.last <= r.first)
    return "--shard " + std::to_string(s.part) + "/" + std::to_string(s.parts) + " holds no paths: a run of " +
           std::to_string(s.paths) + " paths has " + std::to_string(r.count) + " chunks, so N may be at most " +
           std::to_string(r.count);
  if (s.run.threads < 0) return "--threads must be >= 0 (0: all cores), got " + std::to_string(s.run.threads);
  if (s.max_scatter < -1 || s.max_scatter > kSafetyMaxScatter)
    return "--max-scatter must be -1 (no limit) or in 0.." + std::to_string(kSafetyMaxScatter) +
           ", got " + std::to_string(s.max_scatter);
  std::int64_t cells = 0;
  try {
    cells = grid_cell_count(s.grid);
  } catch (const std::invalid_argument& e) {
    return std::string(e.what());
  }
  if (double bytes = table_bytes(cells, s.alpha_bins); bytes > kMaxTableBytes)
    return "--grid " + s.grid + " with --alpha-bins " + std::to_string(s.alpha_bins) + " needs about " +
           fmt::format("{:g}", bytes / (1 << 30)) + " GiB of memory; stf keeps tables up to " + fmt::format("{:g}", kMaxTableBytes / (1 << 30)) +
           " GiB (use fewer alpha bins or a coarser grid)";
  return std::nullopt;
}

double table_bytes(std::int64_t cells, int alpha_bins) { return double(cells) * (16.0 * alpha_bins + 40); }

ChunkRange chunk_range(const PrecomputeSettings& s) {
  const std::int64_t per_chunk = chunk_paths(s.paths);
  ChunkRange r;
  r.count = (s.paths + per_chunk - 1) / per_chunk;
  r.first = r.count * s.part / s.parts;
  r.last = r.count * (s.part + 1) / s.parts;
  return r;
}

namespace {

// The walk of one run (or part) over worker threads: chunks are taken from a shared counter,
// and each finished chunk is added to the one shared tally and marked done, under one lock, so
// a checkpoint taken under that lock is always consistent.
class Driver {
 public:
  Driver(const WalkSetup& setup, const PrecomputeSettings& s, const Checkpointing& checkpointing)
      : setup_(setup), s_(s), range_(chunk_range(s)), per_chunk_(chunk_paths(s.paths)), checkpointing_(checkpointing) {
    state_.tally = Tally(s.alpha_bins, setup.grid->cell_count());
    state_.done.assign(std::size_t(range_.last - range_.first), 0);
    if (checkpointing.resume) state_ = *checkpointing.resume;
    for (std::int64_t c = range_.first; c < range_.last; ++c)
      if (!state_.done[std::size_t(c - range_.first)]) todo_.push_back(c);
    for (std::int64_t c = range_.first; c < range_.last; ++c) total_paths_ += paths_of(c);
    paths_done_ = total_paths_;
    for (std::int64_t c : todo_) paths_done_ -= paths_of(c);
  }

  std::int64_t paths_of(std::int64_t c) const { return std::min(per_chunk_, s_.paths - c * per_chunk_); }
  std::int64_t total_paths() const { return total_paths_; }
  std::int64_t paths_done() const { return paths_done_.load(); }
  std::int64_t chunks_to_do() const { return std::int64_t(todo_.size()); }
  Progress& state() { return state_; }

  // Walks the i-th chunk still to do in the worker's `chunk` and adds it to the tally; false if
  // cancelled.
  bool walk(std::size_t i, ChunkTally& chunk, const std::atomic<bool>* cancel) {
    const WalkControl control{cancel, &paths_done_};
    const std::int64_t c = todo_[i];
    if (!walk_chunk(setup_, {std::uint64_t(s_.seed), std::uint64_t(c), c * per_chunk_, paths_of(c)}, chunk, control))
      return false;
    std::lock_guard<std::mutex> lock(mutex_);
    chunk.add_to(state_.tally);
    chunk.clear();
    state_.done[std::size_t(c - range_.first)] = 1;
    save_if_due();
    return true;
  }

 private:
  // Called under the lock: every `seconds`, the sink gets the chunks done so far.
  void save_if_due() {
    if (!checkpointing_.save) return;
    auto now = std::chrono::steady_clock::now();
    if (std::chrono::duration<double>(now - last_save_).count() < checkpointing_.seconds) return;
    checkpointing_.save(state_);
    last_save_ = std::chrono::steady_clock::now();
  }

  const WalkSetup& setup_;
  const PrecomputeSettings& s_;
  const ChunkRange range_;
  const std::int64_t per_chunk_;
  const Checkpointing& checkpointing_;
  Progress state_;
  std::vector<std::int64_t> todo_;
  std::int64_t total_paths_ = 0;
  std::atomic<std::int64_t> paths_done_{0};
  std::mutex mutex_;
  std::chrono::steady_clock::time_point last_save_ = std::chrono::steady_clock::now();
};

// Runs the driver's chunks over the run's threads (stf/core/parallel.h), each worker walking
// into its own chunk tally, reporting progress every 100 ms; false if a chunk failed or the run
// was cancelled.
bool run_workers(Driver& driver, const RunContext& run) {
  std::vector<ChunkTally> chunks(std::size_t(run.workers(driver.chunks_to_do())));
  const auto told = [&] { run.tell("", driver.paths_done(), driver.total_paths()); };
  return parallel_for(
      driver.chunks_to_do(), run,
      [&](std::int64_t i, int worker) { return driver.walk(std::size_t(i), chunks[std::size_t(worker)], run.cancel); },
      run.progress ? std::function<void()>(told) : std::function<void()>());
}

// The table of a finished run's tally (its counts moved out).
Table tally_table(Tally& tally, const Medium& medium, const PrecomputeSettings& s, const ChunkRange& range,
                  const DirectionGrid& grid) {
  Table table;
  table.medium = medium;
  table.seed = s.seed;
  table.max_scatter = s.max_scatter;
  table.safety_cap = kSafetyMaxScatter;
  table.chunk_first = range.first, table.chunk_last = range.last, table.chunk_count = range.count;
  table.run_paths = s.paths;
  lay_out(table, grid, s.alpha_bins);
  for (int h = 0; h < 2; ++h) table.weight_half[h] = std::move(tally.counts[h]);
  table.escaped_weight = double(tally.escaped);
  table.uncollided_half = {double(tally.uncollided[0]), double(tally.uncollided[1])};
  table.once = tally.once.sorted();
  table.sub_bins = kSubBins;
  for (int h = 0; h < 2; ++h) table.multiple_sub_half[h] = std::move(tally.multiple_sub[h]);
  table.absorbed_weight = double(tally.absorbed);
  table.truncated_weight = double(tally.truncated);
  table.collisions = std::int64_t(tally.collisions);
  table.absorbed_collisions = tally.absorbed_collisions_known ? std::int64_t(tally.absorbed_collisions) : -1;
  table.generator = "stf " STF_VERSION;
  return table;
}

}  // namespace

std::optional<Table> precompute(const Medium& medium, const PrecomputeSettings& s, const Checkpointing& checkpointing) {
  if (auto error = validate(medium, s)) throw std::invalid_argument(*error);
  auto start = std::chrono::steady_clock::now();
  std::unique_ptr<DirectionGrid> grid = make_grid(s.grid);

  WalkSetup setup;
  setup.tau = medium.tau();
  setup.albedo = medium.albedo();
  setup.g = medium.g;
  setup.max_scatter = s.max_scatter < 0 ? kSafetyMaxScatter : s.max_scatter;
  setup.alpha_bins = s.alpha_bins;
  setup.grid = grid.get();

  Driver driver(setup, s, checkpointing);
  const ChunkRange range = chunk_range(s);
  if (!run_workers(driver, s.run)) return std::nullopt;
  s.run.tell("", driver.total_paths(), driver.total_paths());
  Table table = tally_table(driver.state().tally, medium, s, range, *grid);
  table.paths = driver.total_paths();
  table.runtime_s = seconds_since(start);
  return table;
}

}  // namespace stf
