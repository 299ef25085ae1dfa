#include "precompute.h"

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <thread>
#include <vector>

#include "grid.h"
#include "walk.h"

namespace stf {

namespace {

std::string number(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

}  // namespace

std::optional<std::string> validate(const Medium& m, const PrecomputeSettings& s) {
  if (!(std::isfinite(m.sigma_s) && m.sigma_s >= 0))
    return "--sigma-s must be a finite number >= 0, got " + number(m.sigma_s);
  if (!(std::isfinite(m.sigma_a) && m.sigma_a >= 0))
    return "--sigma-a must be a finite number >= 0, got " + number(m.sigma_a);
  if (!(m.g > -1 && m.g < 1)) return "--g must be in (-1, 1), got " + number(m.g);
  if (!(std::isfinite(m.radius) && m.radius > 0))
    return "--radius must be a finite number > 0, got " + number(m.radius);
  if (!(m.sigma_t() > 0))
    return "--sigma-s and --sigma-a must not both be 0 (a vacuum has no table)";
  if (!(std::isfinite(m.tau()) && m.tau() <= kMaxTau))
    return "--radius times (--sigma-s + --sigma-a) must be at most " + number(kMaxTau) + ", got " + number(m.tau());
  if (s.alpha_bins < 1 || s.alpha_bins > 100000)
    return "--alpha-bins must be in 1..100000, got " + std::to_string(s.alpha_bins);
  if (s.paths < 1) return "--paths must be at least 1, got " + std::to_string(s.paths);
  if (s.threads < 0) return "--threads must be >= 0 (0: all cores), got " + std::to_string(s.threads);
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
           number(bytes / (1 << 30)) + " GiB of memory; stf keeps tables up to " + number(kMaxTableBytes / (1 << 30)) +
           " GiB (use fewer alpha bins or a coarser grid)";
  return std::nullopt;
}

double table_bytes(std::int64_t cells, int alpha_bins) { return double(cells) * (16.0 * alpha_bins + 40); }

std::optional<Table> precompute(const Medium& medium, const PrecomputeSettings& s,
                                const std::atomic<bool>* cancel, const ProgressFn& progress) {
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

  const std::int64_t per_chunk = chunk_paths(s.paths);
  const std::int64_t chunks = (s.paths + per_chunk - 1) / per_chunk;
  int threads = s.threads > 0 ? s.threads : int(std::max(1u, std::thread::hardware_concurrency()));
  threads = int(std::min<std::int64_t>(threads, chunks));

  std::atomic<std::int64_t> next_chunk{0}, paths_done{0};
  int running = threads;  // guarded by `mutex`
  std::mutex mutex;
  std::condition_variable finished;
  std::atomic<bool> stopped{false};
  Tally tally(s.alpha_bins, grid->cell_count());  // one table, shared by all threads
  std::mutex tally_mutex;
  auto worker = [&] {
    WalkControl control{cancel, &paths_done};
    ChunkTally chunk;
    for (std::int64_t c; (c = next_chunk.fetch_add(1)) < chunks;) {
      std::int64_t first = c * per_chunk;
      std::int64_t count = std::min(per_chunk, s.paths - first);
      if (!walk_chunk(setup, std::uint64_t(s.seed), std::uint64_t(c), first, count, chunk, control)) {
        stopped = true;
        break;
      }
      std::lock_guard<std::mutex> lock(tally_mutex);
      chunk.add_to(tally);
      chunk.clear();
    }
    std::lock_guard<std::mutex> lock(mutex);
    --running;
    finished.notify_one();
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) pool.emplace_back(worker);
  auto seconds = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  // Report progress every 100 ms until the workers are done; wake at once when they are.
  for (std::unique_lock<std::mutex> lock(mutex); running > 0;) {
    if (finished.wait_for(lock, std::chrono::milliseconds(100), [&] { return running == 0; })) break;
    if (progress) progress(paths_done.load(), s.paths, seconds());
  }
  for (auto& th : pool) th.join();
  if (stopped || (cancel && cancel->load())) return std::nullopt;
  if (progress) progress(s.paths, s.paths, seconds());

  Table table;
  table.medium = medium;
  table.paths = s.paths;
  table.seed = s.seed;
  table.max_scatter = s.max_scatter;
  table.safety_cap = kSafetyMaxScatter;
  table.grid = grid->spec();
  table.alpha_bins = s.alpha_bins;
  table.cells = grid->cell_count();
  for (int i = 0; i <= s.alpha_bins; ++i) table.alpha_edges.push_back(kPi * i / s.alpha_bins);
  table.alpha_edges.back() = kPi;
  for (std::int64_t c = 0; c < table.cells; ++c) {
    Vec3 v = grid->centre(c);
    table.direction.push_back({v.x, v.y, v.z});
  }
  table.solid_angle = grid->solid_angles();
  for (int h = 0; h < 2; ++h) table.weight_half[h] = std::move(tally.counts[h]);
  table.escaped_weight = double(tally.escaped);
  table.absorbed_weight = double(tally.absorbed);
  table.truncated_weight = double(tally.truncated);
  table.collisions = std::int64_t(tally.collisions);
  table.runtime_s = seconds();
  table.generator = "stf " STF_VERSION;
  return table;
}

}  // namespace stf
