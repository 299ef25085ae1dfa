// `stf precompute`: walk paths in a sphere of medium and write the raw table; one part of the
// run with --shard, all of it over MPI ranks under mpirun; `stf merge`: parts into the table.
#include <CLI/CLI.hpp>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>
#include <thread>

#include "cli.h"
#include "stf/core/files.h"
#include "mpi.h"
#include "stf/precompute/parts.h"
#include "stf/precompute/precompute.h"
#include "stf/precompute/walk.h"

namespace stf::cli {

namespace {

struct PrecomputeOptions {
  Medium medium;
  PrecomputeSettings settings;
  std::string alpha_bins = "90", paths = "1e6", seed = "1", threads = "0", max_scatter = "-1";
  std::string shard;
  bool resume = false, quiet = false;
  double checkpoint_seconds = 30;
  std::string output;
};

// "K/N": part K of N.
void parse_shard(const std::string& text, PrecomputeSettings& s) {
  std::size_t slash = text.find('/');
  if (slash == std::string::npos) fail("--shard must be K/N (part K of N, 0 <= K < N), got '" + text + "'");
  s.parts = int(parse_count(text.substr(slash + 1), "--shard N", 1, 1 << 20));
  s.part = int(parse_count(text.substr(0, slash), "--shard K", 0, s.parts - 1));
}

bool exists(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0;
}

PrecomputeSettings settings_of(const PrecomputeOptions& o) {
  PrecomputeSettings s = o.settings;
  s.alpha_bins = int(parse_count(o.alpha_bins, "--alpha-bins", 1, kMaxAlphaBins));
  s.paths = parse_count(o.paths, "--paths", 1, std::int64_t(1) << 50);
  s.seed = parse_count(o.seed, "--seed", 0, INT64_MAX);
  s.run.threads = int(parse_count(o.threads, "--threads", 0, 4096));
  s.max_scatter = parse_count(o.max_scatter, "--max-scatter", -1, kSafetyMaxScatter);
  if (!o.shard.empty()) parse_shard(o.shard, s);
  if (world().size > 1) {
    if (!o.shard.empty()) fail("--shard and mpirun exclude each other: under mpirun every rank is a part");
    s.part = world().rank, s.parts = world().size;
    if (s.run.threads == 0) {  // the node's cores, shared by its ranks
      const char* local = std::getenv("OMPI_COMM_WORLD_LOCAL_SIZE");
      int ranks_here = local ? std::max(1, std::atoi(local)) : 1;
      s.run.threads = std::max(1, int(std::thread::hardware_concurrency()) / ranks_here);
    }
  }
  if (!(o.checkpoint_seconds > 0)) fail("--checkpoint-seconds must be > 0");
  if (auto error = validate(o.medium, s)) fail(*error);
  return s;
}

// Beside the output: one per process of the run (each MPI rank has its own).
std::string checkpoint_path(const std::string& output) {
  if (world().size == 1) return output + ".checkpoint";
  return output + ".rank-" + std::to_string(world().rank) + "-of-" + std::to_string(world().size) + ".checkpoint";
}

// A checkpoint beside the output that a run on another number of processes left
// (OUT.checkpoint of one process, OUT.rank-R-of-N.checkpoint of N ranks), or "": --resume must
// run as that run did, not start from nothing.
std::string other_runs_checkpoint(const std::string& output) {
  namespace fs = std::filesystem;
  const fs::path out(output);
  const std::string name = out.filename().string(), suffix = ".checkpoint";
  const std::string mine = world().size == 1 ? "" : "-of-" + std::to_string(world().size) + suffix;
  std::error_code error;
  for (const fs::directory_entry& e : fs::directory_iterator(out.has_parent_path() ? out.parent_path() : ".", error)) {
    const std::string f = e.path().filename().string();
    const bool single = f == name + suffix;
    const bool ranks = f.rfind(name + ".rank-", 0) == 0 && f.size() > suffix.size() &&
                       f.compare(f.size() - suffix.size(), suffix.size(), suffix) == 0;
    const bool same_count = world().size == 1 ? single : ranks && f.size() > mine.size() &&
                                                             f.compare(f.size() - mine.size(), mine.size(), mine) == 0;
    if ((single || ranks) && !same_count) return e.path().string();
  }
  return "";
}

// The state an earlier, killed run of the same command left, when --resume asks for it.
std::optional<Progress> resumable(const PrecomputeOptions& o, const PrecomputeSettings& s, const std::string& path) {
  if (written_in_place(o.output)) {
    if (o.resume) fail("--resume needs -o to name a file: checkpoints are kept beside it");
    return std::nullopt;
  }
  if (std::string other = other_runs_checkpoint(o.output); !other.empty() && !exists(path))
    fail("checkpoint " + other + " is of a run on another number of MPI ranks; resume it with as many ranks (" +
         (other.find(".rank-") == std::string::npos ? std::string("one process") : "mpirun -n N, N as in its name") +
         "), or remove it");
  if (!exists(path)) {
    if (o.resume && !o.quiet && world().root()) std::fprintf(stderr, "stf precompute: no checkpoint %s; starting from the beginning\n", path.c_str());
    return std::nullopt;
  }
  if (!o.resume)
    fail("checkpoint " + path + " holds an unfinished run; rerun the same command with --resume to finish it, or remove it");
  try {
    return read_checkpoint(path, run_fingerprint(o.medium, s), chunk_range(s), s.alpha_bins, grid_cell_count(s.grid));
  } catch (const std::runtime_error& e) {
    fail(std::string("--resume: ") + e.what());
  }
}

void summarise(const PrecomputeOptions& o, const PrecomputeSettings& s, const Table& t) {
  double n = double(t.paths);
  std::string part = t.is_part() ? " (part " + std::to_string(s.part) + " of " + std::to_string(s.parts) + ": chunks " +
                                       std::to_string(t.chunk_first) + ".." + std::to_string(t.chunk_last - 1) + " of " +
                                       std::to_string(t.chunk_count) + ")"
                                 : "";
  std::string ranks = world().size > 1 ? " on " + std::to_string(world().size) + " MPI ranks" : "";
  std::fprintf(stderr,
               "stf precompute: %lld paths%s%s in %.3g s (%.3g paths/s, %.3g collisions/path); "
               "escaped %.4f, absorbed %.4f, truncated %.4f -> %s\n",
               (long long)t.paths, part.c_str(), ranks.c_str(), t.runtime_s, n / t.runtime_s, double(t.collisions) / n,
               t.escaped_weight / n, t.absorbed_weight / n, t.truncated_weight / n, o.output.c_str());
}

void run_precompute(const PrecomputeOptions& o) {
  PrecomputeSettings s;
  std::optional<AtomicOutput> out;
  std::optional<Progress> resumed;
  const std::string checkpoint = checkpoint_path(o.output);
  on_every_rank([&] {
    s = settings_of(o);
    if (world().root()) out.emplace(o.output, "-o");  // claimed before any work
    if (!written_in_place(o.output)) {  // a killed run's half-saved checkpoint
      const std::filesystem::path c(checkpoint);
      remove_orphans(c.has_parent_path() ? c.parent_path().string() : ".", c.filename().string() + ".tmp-");
    }
    resumed = resumable(o, s, checkpoint);
  });

  Checkpointing checkpointing;
  checkpointing.resume = resumed ? &*resumed : nullptr;
  checkpointing.seconds = o.checkpoint_seconds;
  const std::string fingerprint = run_fingerprint(o.medium, s);
  bool warned = false;
  if (!written_in_place(o.output))  // standard output or a device: no folder to keep them in
    checkpointing.save = [&](const Progress& p) {
      try {
        write_checkpoint(checkpoint, fingerprint, p);
      } catch (const std::exception& e) {  // the run goes on; only its insurance failed
        if (!warned) std::fprintf(stderr, "stf precompute: warning: %s\n", e.what());
        warned = true;
      }
    };
  ProgressBar bar("precompute", o.quiet || !world().root());
  s.run.cancel = &interrupted, s.run.progress = bar.progress();
  auto table = precompute(o.medium, s, checkpointing);
  bar.finish();
  if (any_rank(!table)) {
    if (exists(checkpoint) && world().root())
      std::fprintf(stderr, "stf precompute: the work until %s was saved: rerun with --resume to finish it\n",
                   checkpoint.c_str());
    throw Interrupted();
  }
  sum_to_root(*table);
  on_every_rank([&] {
    if (!world().root()) return;
    out->write(table_file(*table));
  });
  std::remove(checkpoint.c_str());  // the table holds it all now
  if (!o.quiet && world().root()) summarise(o, s, *table);
}

struct MergeOptions {
  std::vector<std::string> parts;
  std::string output;
  bool quiet = false;
};

void run_merge(const MergeOptions& o) {
  std::vector<NamedFile> inputs;
  for (const std::string& p : o.parts) inputs.push_back({p, "part"});
  require_files(inputs);
  AtomicOutput out(o.output, "-o", inputs);
  // First the parts' headers (their weights dropped at once), then one part at a time.
  std::vector<Table> heads;
  for (const std::string& p : o.parts) {
    heads.push_back(read_table(p));
    for (auto& half : heads.back().weight_half) half = {};
    stop_if_interrupted();
  }
  std::vector<std::size_t> order;
  try {
    order = check_parts(heads, o.parts);
  } catch (const std::invalid_argument& e) {
    fail(e.what());
  }
  Table whole = read_table(o.parts[order.front()]);
  for (std::size_t i = 1; i < order.size(); ++i) {
    add_part(whole, read_table(o.parts[order[i]]));
    stop_if_interrupted();
  }
  out.write(table_file(whole));
  if (!o.quiet)
    std::fprintf(stderr, "stf merge: %zu parts, %lld paths (chunks 0..%lld) -> %s\n", o.parts.size(),
                 (long long)whole.paths, (long long)whole.chunk_count - 1, o.output.c_str());
}

}  // namespace

void add_precompute_command(CLI::App& app) {
  auto o = std::make_shared<PrecomputeOptions>();
  CLI::App* cmd = app.add_subcommand(
      "precompute", "Walk paths from the centre of a sphere of medium; write the raw table (HDF5)");
  add_medium_options(*cmd, o->medium, true);
  cmd->add_option("--alpha-bins", o->alpha_bins, "Bins of the exit-point angle alpha on [0, pi]")
      ->capture_default_str();
  cmd->add_option("--grid", o->settings.grid, "Direction cells: csc:N (COBE sky cube) or healpix:NSIDE")
      ->capture_default_str();
  cmd->add_option("--paths", o->paths, "Paths to walk (e.g. 1e6)")->capture_default_str();
  cmd->add_option("--seed", o->seed, "Random seed; the same seed gives the same table for any --threads")
      ->capture_default_str();
  cmd->add_option("--threads", o->threads, "Worker threads (0: all cores)")->capture_default_str();
  cmd->add_option("--max-scatter", o->max_scatter,
                  "Stop a path at collision K+1 and book it as truncated (-1: no limit but the "
                  "safety cap of 1e9 collisions)")
      ->capture_default_str();
  cmd->add_option("--shard", o->shard, "Walk only part K of N of the run (K = 0..N-1); `stf merge` sums the parts");
  cmd->add_flag("--resume", o->resume, "Continue the run a killed process left in OUTPUT.checkpoint");
  cmd->add_option("--checkpoint-seconds", o->checkpoint_seconds,
                  "Save the finished chunks to OUTPUT.checkpoint this often")
      ->capture_default_str();
  cmd->add_flag("--quiet", o->quiet, "No progress bar and no summary line");
  cmd->add_option("-o,--output", o->output, "Output table (HDF5)")->required();
  cmd->callback([o] { run_precompute(*o); });
}

void add_merge_command(CLI::App& app) {
  auto o = std::make_shared<MergeOptions>();
  CLI::App* cmd = app.add_subcommand("merge", "Sum the parts of one run (stf precompute --shard K/N) into its table");
  cmd->add_option("parts", o->parts, "Parts (HDF5 tables written with --shard)")->required();
  cmd->add_option("-o,--output", o->output, "Output table (HDF5)")->required();
  cmd->add_flag("--quiet", o->quiet, "No summary line");
  cmd->callback([o] { run_merge(*o); });
}

}  // namespace stf::cli
