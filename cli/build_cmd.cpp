// `stf build`: plan a scene, compute what it needs (cached), pack it for the sampler.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <optional>

#include "stf/scene/build.h"
#include "cli.h"
#include "stf/render/pack_recipe.h"
#include "stf/scene/render_scene.h"
#include "mpi.h"
#include "stf/scene/plan.h"
#include "stf/scene/scene.h"

namespace stf::cli {

namespace {

struct BuildOptions {
  std::string scene, output, cache;
  std::string threads = "0";
  bool plan_only = false, json = false, quiet = false, strict = false;
  double tolerance = 0.02;          // render scenes: as stf render's --tolerance
  std::string model = "hvmf:auto";  // render scenes: as stf render's --model
};

// The recipe of `o.scene`: a pack recipe as written, or for a render scene (one with
// [[objects]]) the pack `stf render --method stf` would build for it (render/pack_recipe.h).
scene::Scene recipe_of(const BuildOptions& o, const CLI::App& cmd, bool render_scene, int threads) {
  if (!render_scene) {
    if (cmd.count("--tolerance") || cmd.count("--model"))
      fail("--tolerance and --model apply to render scenes; a pack recipe sets them in [settings]");
    return scene::read_scene(o.scene);
  }
  if (!(o.tolerance > 0 && o.tolerance < 1)) fail("--tolerance must be in (0, 1), got " + std::to_string(o.tolerance));
  const scene::RenderScene sc = scene::read_render_scene(o.scene);
  const render::SceneGeometry geometry(sc, render::FreeRadius::kGrid, 256, RunContext{threads, &interrupted, {}});
  stop_if_interrupted();
  scene::Settings settings;
  settings.tolerance = o.tolerance, settings.model = o.model;
  return render::scene_pack_recipe(sc, geometry, settings);
}

// recipe_of `o.scene`, telling whether it is a render scene; a scene's error in one line.
scene::Scene read_recipe(const BuildOptions& o, const CLI::App& cmd, int threads, bool& render_scene) {
  try {
    render_scene = scene::is_render_scene(o.scene);
    return recipe_of(o, cmd, render_scene, threads);
  } catch (const scene::SceneError& e) {
    fail(e.what());
  }
}

// The cache a build reads and fills: --cache; for a render scene stf render's own (so that
// renders find what was built), for a recipe SCENE.toml.cache.
std::string cache_of(const BuildOptions& o, bool render_scene) {
  if (!o.cache.empty()) return o.cache;
  const std::string shared = render::default_cache_folder();
  return render_scene && !shared.empty() ? shared : o.scene + ".cache";
}

// One line per entry this build computed that it could not certify within the tolerance (once,
// when built: a build that finds it cached counts it in the summary line only).
void warn_unmet(const scene::Plan& before, const scene::Plan& plan, bool strict) {
  std::vector<const scene::PlanEntry*> unmet = scene::unmet_entries(plan);
  if (unmet.empty()) return;
  for (const scene::PlanEntry* e : unmet)
    if (scene::computed_by(before, *e))
      std::fprintf(stderr, "stf build: warning: tau %g albedo %g g %g (%s) is certified only within TV %.3g, not %g\n",
                   e->tau, e->albedo, e->g, e->media.front().c_str(), e->resolution.tv_bound, plan.settings.tolerance);
  int entries = 0;
  for (const scene::PlanEntry& e : plan.entries) entries += e.action != "skip";
  char summary_text[160];
  std::snprintf(summary_text, sizeof summary_text, "%zu of %d entries not certified within tolerance %g", unmet.size(),
                entries, plan.settings.tolerance);
  const std::string summary = summary_text;
  if (strict) throw ToleranceNotMet(summary + " (--strict)");
  std::fprintf(stderr, "stf build: warning: %s\n", summary.c_str());
}

void run_build(const BuildOptions& o, const CLI::App& cmd) {
  if (o.plan_only && !o.output.empty()) fail("-o and --plan-only exclude each other: --plan-only writes no pack");
  if (!o.plan_only && o.output.empty()) fail("-o must name the output pack (or use --plan-only)");
  if (o.json && o.output == "-") fail("--json and -o - would both write to stdout; give -o a file");
  const int threads = int(parse_count(o.threads, "--threads", 0, 4096));
  bool render_scene = false;
  const scene::Scene sc = read_recipe(o, cmd, threads, render_scene);
  const std::string cache = cache_of(o, render_scene);
  if (!o.plan_only) require_writable_folder(cache, "--cache");
  if (!o.output.empty() && inside_folder(o.output, cache))
    fail("-o '" + o.output + "' is inside the cache '" + cache + "', which holds the tables and models the build reads; choose another folder");
  scene::Plan plan = scene::make_plan(sc, cache);
  if (o.plan_only) {
    if (o.json) std::fputs(scene::plan_json(plan).c_str(), stdout);
    else if (!o.quiet) std::fputs(scene::plan_table(plan).c_str(), stderr);
    return;
  }
  const World& w = world();
  std::optional<AtomicOutput> pack;
  on_every_rank([&] {  // before any work
    if (w.root()) pack.emplace(o.output, "-o", std::vector<NamedFile>{{o.scene, "the scene"}});
  });
  if (!o.quiet && w.root()) std::fputs(scene::plan_table(plan).c_str(), stderr);
  // Under mpirun every rank computes its share of the entries into the shared cache.
  int computed = 0;
  std::string failure;
  SphereProgress progress(w.size > 1 ? "stf build: rank " + std::to_string(w.rank) : "stf build", o.quiet);
  try {
    computed = scene::compute_entries(
        plan, threads,
        [&](int i, int n, const scene::PlanEntry& e) {
          progress.start(i, n, fmt::format("tau {:g}, albedo {:g}, g {:g} ({})", e.tau, e.albedo, e.g, e.media.front()));
        },
        &interrupted, w.rank, w.size);
  } catch (const std::exception& e) {
    failure = e.what();
  }
  progress.finish();
  if (any_rank(!failure.empty())) {
    stop_if_interrupted();  // Ctrl-C: say so (finished entries stay in the cache)
    // main() prints rank 0's errors only: another rank names its own here.
    if (!failure.empty() && !w.root()) std::fprintf(stderr, "stf: error (rank %d): %s\n", w.rank, failure.c_str());
    if (!failure.empty()) fail(failure);
    if (!w.root()) return;
    fail("another MPI rank failed; finished entries stay in the cache");
  }
  if (!w.root()) return;
  // What was built, as the cache now holds it.
  scene::Plan built = scene::make_plan(sc, cache);
  pack->stage(bytes_of(scene::scene_pack(sc, built)));
  warn_unmet(plan, built, o.strict);
  pack->commit();
  if (o.json) std::fputs(scene::plan_json(built).c_str(), stdout);
  if (!o.quiet) std::fprintf(stderr, "stf build: computed %d entries, pack -> %s\n", computed, o.output.c_str());
}

}  // namespace

void add_build_command(CLI::App& app) {
  auto o = std::make_shared<BuildOptions>();
  CLI::App* cmd = app.add_subcommand("build", "Plan, compute (cached) and pack what a scene's media need");
  cmd->add_option("scene", o->scene, "A render scene (builds the pack stf render would use) or a pack recipe (TOML)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", o->output, "Output pack");
  cmd->add_flag("--plan-only", o->plan_only, "Print the plan; compute nothing");
  cmd->add_flag("--json", o->json,
                "The plan as JSON on stdout (after a build: as built, with what each entry got)");
  cmd->add_flag("--strict", o->strict,
                "Exit with status 3 (and write no pack) when an entry is not certified within the tolerance");
  cmd->add_option("--cache", o->cache,
                  "Cache folder (default: a render scene's is stf render's, $STF_CACHE_DIR or ~/.cache/stf; a "
                  "recipe's SCENE.toml.cache)");
  cmd->add_option("--tolerance", o->tolerance, "Render scenes: TV distance each sphere is certified within")
      ->capture_default_str();
  cmd->add_option("--model", o->model, "Render scenes: the spheres' model family (a fitter's --model)")
      ->capture_default_str();
  cmd->add_option("--threads", o->threads, "Worker threads (0: all cores)")->capture_default_str();
  cmd->add_flag("--quiet", o->quiet, "No plan table and no progress");
  cmd->callback([o, cmd] { run_build(*o, *cmd); });
}

}  // namespace stf::cli
