// `stf precompute`: walk paths in a sphere of medium and write the raw table.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <memory>

#include "cli.h"
#include "precompute.h"
#include "walk.h"

namespace stf::cli {

namespace {

struct PrecomputeOptions {
  Medium medium;
  PrecomputeSettings settings;
  std::string alpha_bins = "90", paths = "1e6", seed = "1", threads = "0", max_scatter = "-1";
  bool quiet = false;
  std::string output;
};

void run_precompute(const PrecomputeOptions& o) {
  PrecomputeSettings s = o.settings;
  s.alpha_bins = int(parse_count(o.alpha_bins, "--alpha-bins", 1, 100000));
  s.paths = parse_count(o.paths, "--paths", 1, std::int64_t(1) << 50);
  s.seed = parse_count(o.seed, "--seed", 0, INT64_MAX);
  s.threads = int(parse_count(o.threads, "--threads", 0, 4096));
  s.max_scatter = parse_count(o.max_scatter, "--max-scatter", -1, kSafetyMaxScatter);
  if (auto error = validate(o.medium, s)) fail(*error);

  AtomicOutput out(o.output, "-o");
  ProgressBar bar("precompute", o.quiet);
  auto table = precompute(o.medium, s, &interrupted,
                          [&](std::int64_t done, std::int64_t total, double seconds) {
                            bar.update(done, total, seconds);
                          });
  bar.finish();
  if (!table) throw Interrupted();
  write_table(*table, out.temp_path());
  out.commit();
  if (!o.quiet) {
    double n = double(table->paths);
    std::fprintf(stderr,
                 "stf precompute: %lld paths in %.3g s (%.3g paths/s, %.3g collisions/path); "
                 "escaped %.4f, absorbed %.4f, truncated %.4f -> %s\n",
                 (long long)table->paths, table->runtime_s, n / table->runtime_s,
                 double(table->collisions) / n, table->escaped_weight / n,
                 table->absorbed_weight / n, table->truncated_weight / n, o.output.c_str());
  }
}

}  // namespace

void add_precompute_command(CLI::App& app) {
  auto o = std::make_shared<PrecomputeOptions>();
  CLI::App* cmd = app.add_subcommand(
      "precompute", "Walk paths from the centre of a sphere of medium; write the raw table (HDF5)");
  cmd->add_option("--sigma-s", o->medium.sigma_s, "Scattering coefficient (>= 0)")->required();
  cmd->add_option("--sigma-a", o->medium.sigma_a, "Absorption coefficient (>= 0)")->required();
  cmd->add_option("--g", o->medium.g, "Henyey-Greenstein asymmetry, in (-1, 1)")->required();
  cmd->add_option("--radius", o->medium.radius, "Sphere radius (> 0)")->capture_default_str();
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
  cmd->add_flag("--quiet", o->quiet, "No progress bar and no summary line");
  cmd->add_option("-o,--output", o->output, "Output table (HDF5)")->required();
  cmd->callback([o] { run_precompute(*o); });
}

}  // namespace stf::cli
