// `stf build`: plan a scene, compute what it needs (cached), pack it for the sampler.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <memory>

#include "build.h"
#include "cli.h"
#include "plan.h"
#include "scene.h"

namespace stf::cli {

namespace {

struct BuildOptions {
  std::string scene, output, cache;
  std::string threads = "0";
  bool plan_only = false, json = false, quiet = false;
};

void run_build(const BuildOptions& o) {
  scene::Scene sc;
  try {
    sc = scene::read_scene(o.scene);
  } catch (const scene::SceneError& e) {
    fail(e.what());
  }
  if (!o.plan_only && o.output.empty()) fail("-o must name the output pack (or use --plan-only)");
  const std::string cache = o.cache.empty() ? o.scene + ".cache" : o.cache;
  scene::Plan plan = scene::make_plan(sc, cache);
  if (o.json) std::fputs(scene::plan_json(plan).c_str(), stdout);
  if (!o.json && !o.quiet) std::fputs(scene::plan_table(plan).c_str(), stderr);
  if (o.plan_only) return;
  const int threads = int(parse_count(o.threads, "--threads", 0, 4096));
  AtomicOutput check(o.output, "-o");  // fail early on an unwritable output
  install_interrupt_handler();
  int computed = scene::build(
      sc, plan, check.temp_path(), threads,
      [&](int i, int n, const scene::PlanEntry& e) {
        if (!o.quiet) std::fprintf(stderr, "stf build: [%d/%d] tau %g albedo %g g %g\n", i + 1, n, e.tau, e.albedo, e.g);
      },
      &interrupted);
  check.commit();
  if (!o.quiet) std::fprintf(stderr, "stf build: computed %d entries, pack -> %s\n", computed, o.output.c_str());
}

}  // namespace

void add_build_command(CLI::App& app) {
  auto o = std::make_shared<BuildOptions>();
  CLI::App* cmd = app.add_subcommand("build", "Plan, compute (cached) and pack what a scene's media need");
  cmd->add_option("scene", o->scene, "Scene file (TOML)")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", o->output, "Output pack");
  cmd->add_flag("--plan-only", o->plan_only, "Print the plan; compute nothing");
  cmd->add_flag("--json", o->json, "The plan as JSON on stdout");
  cmd->add_option("--cache", o->cache, "Cache folder (default: SCENE.toml.cache)");
  cmd->add_option("--threads", o->threads, "Worker threads (0: all cores)")->capture_default_str();
  cmd->add_flag("--quiet", o->quiet, "No plan table and no progress");
  cmd->callback([o] { run_build(*o); });
}

}  // namespace stf::cli
