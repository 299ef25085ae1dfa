// `stf grid cloud`: a procedural cumulus (stf/media/cloud.h) written as a density grid a scene can
// fill an object with (.vdb, or .npy with the bounds it prints), to try grids without a file.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "cli.h"
#include "stf/media/cloud.h"
#include "stf/media/grid_file.h"

namespace stf::cli {

namespace {

struct CloudOptions {
  std::string output, size = "128", seed = "1";
  bool quiet = false;
};

// What the summary says of the values.
struct CloudStats {
  std::int64_t non_zero = 0, full = 0;  // full: exactly 1, the constant core
  float max = 0;
};

CloudStats stats_of(const std::vector<float>& values) {
  CloudStats s;
  for (const float v : values) {
    s.non_zero += v > 0;
    s.full += v == 1.0f;
    s.max = std::max(s.max, v);
  }
  return s;
}

// Writes the grid to the output's temporary file (its folder, so the rename is atomic) and puts
// it in place; a failure names the output, not the temporary.
void write_cloud(AtomicOutput& out, media::GridFormat format, media::Cumulus& cloud) {
  try {
    media::write_grid(out.temp_path(), format, std::move(cloud.values), cloud.size, cloud.bounds);
  } catch (const std::runtime_error& e) {
    std::string what = e.what();
    if (what.rfind(out.temp_path(), 0) == 0) what = what.substr(out.temp_path().size());
    fail(fmt::format("-o '{}'{}", out.named().path, what));
  }
  out.commit();
}

void run_cloud(const CloudOptions& o) {
  const std::optional<media::GridFormat> format = media::grid_format(o.output);
  if (!format)
    fail(fmt::format("-o '{}': a density grid is written as .vdb or .npy (by its extension)",
                     o.output));
  const int size = int(parse_count(o.size, "--size", media::kMinCloudSize, media::kMaxCloudSize));
  const auto seed = std::uint64_t(parse_count(o.seed, "--seed", 0, INT64_MAX));
  try {
    media::load_grid_writer(*format);  // before any work: a missing module is told at once
  } catch (const std::runtime_error& e) {
    fail(e.what());
  }
  AtomicOutput out(o.output, "-o");
  const auto start = std::chrono::steady_clock::now();
  media::Cumulus cloud = media::cumulus(size, seed, RunContext{0, &interrupted, {}});
  stop_if_interrupted();
  const CloudStats s = stats_of(cloud.values);
  write_cloud(out, *format, cloud);
  if (o.quiet) return;
  if (*format == media::GridFormat::npy)
    std::printf("bounds = [[-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]]\n");
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::fprintf(stderr,
               "stf grid cloud: %d^3 voxels, %lld non-zero (%.1f %%), %.1f %% of them at density "
               "1, max density %g, %.2f s -> %s\n",
               size, static_cast<long long>(s.non_zero),
               100.0 * double(s.non_zero) / (double(size) * size * size),
               100.0 * double(s.full) / double(std::max<std::int64_t>(1, s.non_zero)),
               double(s.max), seconds, o.output.c_str());
}

}  // namespace

void add_grid_command(CLI::App& app) {
  CLI::App* grid = app.add_subcommand("grid", "Make density grids for media (.vdb, .npy)");
  grid->require_subcommand(1);
  auto o = std::make_shared<CloudOptions>();
  CLI::App* cmd = grid->add_subcommand("cloud",
                                       "Write a procedural cumulus of density in [0, 1] (exactly 1 "
                                       "over its core) filling the cube [-0.5, 0.5]^3");
  cmd->add_option("-o,--output", o->output,
                  "The grid: .vdb (FloatGrid 'density', placed by its transform) or .npy (float32; "
                  "prints its bounds)")
      ->required();
  cmd->add_option("--size", o->size, "Voxels per edge, 16 to 1024 (the same cloud, finer)")
      ->capture_default_str();
  cmd->add_option("--seed", o->seed, "Random seed: the same seed gives the same cloud")
      ->capture_default_str();
  cmd->add_flag("--quiet", o->quiet, "No bounds line, no summary");
  cmd->callback([o] { run_cloud(*o); });
}

}  // namespace stf::cli
