// `stf render`: the one-sphere scene (stf/render/sphere_scene.h) by brute force or through shell
// strides, to show that a renderer using stf gets the brute-force picture, and how much sooner.
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <H5Cpp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>

#include "stf/scene/build.h"
#include "cli.h"
#include "render_cmd.h"
#include "stf/core/h5io.h"
#include "stf/scene/plan.h"
#include "stf/render/image_file.h"
#include "stf/render/pack_recipe.h"
#include "stf/precompute/precompute.h"
#include "stf/render/render.h"
#include "stf/render/scene_geometry.h"
#include "stf/render/sphere_scene.h"
#include "stf/core/clock.h"
#include "stf/fit/fit_settings.h"

namespace stf::cli {

namespace {

// Where packs built for renders are cached: --cache, else render::default_cache_folder().
std::string cache_folder(const RenderOptions& o) {
  if (!o.cache.empty()) return o.cache;
  const std::string folder = render::default_cache_folder();
  if (folder.empty()) fail("no cache folder for the pack: give --cache (or set STF_CACHE_DIR)");
  return folder;
}

// A plan entry as a person reads it: "tau 16, albedo 0.999042, g 0.85 (milk (G), ...)".
std::string sphere_name(const scene::PlanEntry& e) {
  std::string media;
  for (const std::string& m : e.media) media += (media.empty() ? "" : ", ") + m;
  return fmt::format("tau {:g}, albedo {:g}, g {:g} ({})", e.tau, e.albedo, e.g, media);
}

// A warning for each sphere this run computed that is certified only within a larger TV
// distance than asked: once, when it is built, not on every render that finds it cached.
void warn_unmet_once(const scene::Plan& before, const scene::Plan& built, double tolerance) {
  for (const scene::PlanEntry* e : scene::unmet_entries(built)) {
    if (scene::computed_by(before, *e))
      std::fprintf(stderr, "stf render: warning: the sphere %s is certified only within TV %.3g, not %g\n",
                   sphere_name(*e).c_str(), e->resolution.tv_bound, tolerance);
  }
}

// `files` and `more` in one list.
std::vector<NamedFile> with(std::vector<NamedFile> files, const std::vector<NamedFile>& more) {
  files.insert(files.end(), more.begin(), more.end());
  return files;
}

}  // namespace

scene::Settings render_pack_settings(const RenderOptions& o) {
  scene::Settings s;
  s.tolerance = o.tolerance;
  s.model = o.model;
  return s;
}

std::vector<PackEntry> build_pack(const scene::Scene& sc, const RenderOptions& o, int threads, PackBuild& build) {
  const auto start = std::chrono::steady_clock::now();
  const std::string cache = cache_folder(o);
  require_writable_folder(cache, "--cache");
  const scene::Plan plan = scene::make_plan(sc, cache);
  try {
    SphereProgress progress("stf render", o.quiet);
    build.spheres_computed = scene::compute_entries(
        plan, threads, [&](int i, int n, const scene::PlanEntry& e) { progress.start(i, n, sphere_name(e)); }, &interrupted);
  } catch (const std::runtime_error&) {
    stop_if_interrupted();  // Ctrl-C: exit 130 (finished spheres stay in the cache)
    throw;
  }
  const scene::Plan built = scene::make_plan(sc, cache);  // now with the certified bounds
  if (!o.quiet) warn_unmet_once(plan, built, o.tolerance);
  ScratchFile pack("pack");
  scene::write_scene_pack(sc, built, pack.path());
  std::vector<PackEntry> entries;
  std::string error;
  if (!read_pack_file(pack.path(), entries, error)) fail("the pack just built: " + error);
  build.seconds = seconds_since(start);
  return entries;
}

std::string precompute_words(const PackBuild& build) {
  if (build.seconds <= 0) return "";
  return fmt::format("; precompute {:.3g} s, {} sphere{} computed", build.seconds, build.spheres_computed,
                     build.spheres_computed == 1 ? "" : "s");
}

std::vector<PackEntry> read_pack_option(const std::string& path) {
  std::vector<PackEntry> entries;
  std::string error;
  if (!read_pack_file(path, entries, error)) fail("--pack: " + path + ": " + error);
  return entries;
}

RenderOutputs::RenderOutputs(const RenderOptions& o, std::vector<NamedFile> inputs)
    : image(o.output, "-o", with({{o.pack, "--pack"}}, inputs)) {
  std::vector<NamedFile> keep = with({{o.pack, "--pack"}, image.named()}, inputs);
  if (!o.exr.empty()) exr.emplace(o.exr, "--exr", keep), keep.push_back(exr->named());
  if (!o.png.empty()) png.emplace(o.png, "--png", keep), keep.push_back(png->named());
  if (!o.json.empty()) json.emplace(o.json, "--json", keep);
}

void RenderOutputs::finish(const render::Image& im, double exposure, const std::string& json_text) {
  const render::Radiance radiance{im.mean, im.width, im.height, im.channels};
  if (exr) render::write_exr(exr->temp_path(), radiance);
  if (png) render::write_png(png->temp_path(), radiance, exposure);
  if (json) json->stage(json_text);
  const auto held = [](std::optional<AtomicOutput>& out) { return out ? &*out : nullptr; };
  commit_all({&image, held(exr), held(png), held(json)});
}

render::ImageSettings image_settings(const RenderOptions& o, const CLI::App& cmd, int width, int height) {
  const bool stf = o.method == "stf";
  if (!stf && (cmd.count("--pack") || cmd.count("--tolerance")))
    fail("--pack and --tolerance apply to --method stf only");
  if (cmd.count("--pack") && cmd.count("--tolerance"))
    fail("--pack and --tolerance exclude each other: --tolerance builds the pack");
  if (!(o.tolerance > 0 && o.tolerance < 1)) fail("--tolerance must be in (0, 1), got " + std::to_string(o.tolerance));
  if (!stf && cmd.count("--model")) fail("--model applies to --method stf only");
  if (cmd.count("--pack") && cmd.count("--model")) fail("--pack and --model exclude each other: --model builds the pack");
  try {
    fit::parse_model_spec(o.model);
  } catch (const std::invalid_argument& e) {
    fail(e.what());
  }
  if (!std::isfinite(o.exposure)) fail("--exposure must be a finite number of stops");
  render::ImageSettings s;
  s.width = cmd.count("--width") ? int(parse_count(o.width, "--width", 1, 8192)) : width;
  s.height = cmd.count("--height") ? int(parse_count(o.height, "--height", 1, 8192)) : height;
  s.spp = parse_count(o.spp, "--spp", 1, std::int64_t(1) << 40);
  s.seed = std::uint64_t(parse_count(o.seed, "--seed", 0, INT64_MAX));
  s.run.threads = int(parse_count(o.threads, "--threads", 0, 4096));
  return s;
}

namespace {

std::string shortest(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", x);
  return buf;
}

// `spheres` null for brute force (or where the pack has none of the medium).
std::string stats_json(const render::Image& image, const PackBuild& build, const SphereLookup* spheres) {
  const int n = spheres ? spheres->size() : 0;
  const nlohmann::ordered_json j = {{"seconds", image.seconds},
                                    {"precompute_seconds", build.seconds},
                                    {"spheres_computed", build.spheres_computed},
                                    {"paths", image.paths},
                                    {"collisions", image.collisions},
                                    {"strides", image.strides},
                                    {"mean_radiance", image.mean_radiance()},
                                    {"spheres", n},
                                    {"smallest_sphere_tau", n > 0 ? spheres->tau(0) : 0.0},
                                    {"largest_sphere_tau", n > 0 ? spheres->tau(n - 1) : 0.0}};
  return j.dump(2) + "\n";
}

void run_sphere_render(const RenderOptions& o, const CLI::App& cmd) {
  for (const char* flag : {"--sigma-s", "--sigma-a", "--g"})
    if (!cmd.count(flag)) fail(std::string("give a scene file, or ") + flag + " (with --sigma-s, --sigma-a and --g) for the sphere");
  if (auto error = validate(o.medium, PrecomputeSettings{})) fail(*error);
  if (o.ideal_strides) fail("--ideal-strides applies to scene files (build/bench/stride_bound bounds the sphere)");
  render::ImageSettings s = image_settings(o, cmd, 64, 64);
  RenderOutputs outputs(o);
  const scene::RenderScene sc = render::sphere_scene(o.medium, s.width, s.height);
  const render::SceneGeometry geometry(sc, render::FreeRadius::kQuery);  // a sphere's free radius is exact

  PackBuild build;
  std::vector<PackEntry> pack;
  if (o.method == "stf")
    pack = o.pack.empty() ? build_pack(render::sphere_pack_recipe(o.medium, render_pack_settings(o)), o, s.run.threads, build)
                          : read_pack_option(o.pack);
  // As the sphere form has always been defined (docs/render.md): radiance only where a path leaves,
  // no shadow rays; scenes cast them.
  render::PathOptions options;
  options.next_event = false;
  const render::ScenePaths paths(sc, geometry, o.method == "stf" ? &pack : nullptr, options);
  if (!o.pack.empty() && !paths.spheres(0, 0))  // most likely the pack of another medium
    fail("--pack: " + o.pack + " has no sphere of albedo " + shortest(o.medium.albedo()) + " and g " + shortest(o.medium.g));
  ProgressBar bar("render", o.quiet);
  s.run.cancel = &interrupted, s.run.progress = bar.progress();
  render::Image image = render::render(sc, paths, s, render::Channels::kOne);
  bar.finish();
  stop_if_interrupted();
  write_image(outputs.image, image, o, s,
              {{"sigma_s", o.medium.sigma_s}, {"sigma_a", o.medium.sigma_a}, {"g", o.medium.g}, {"radius", o.medium.radius}});
  outputs.finish(image, o.exposure, stats_json(image, build, paths.spheres(0, 0)));
  if (!o.quiet)
    std::fprintf(stderr,
                 "stf render: %s, %lld paths in %.3g s (%.3g collisions, %.3g strides per path%s), mean radiance %.6g "
                 "-> %s\n",
                 o.method.c_str(), (long long)image.paths, image.seconds, double(image.collisions) / double(image.paths),
                 double(image.strides) / double(image.paths), precompute_words(build).c_str(), image.mean_radiance(), o.output.c_str());
}

}  // namespace

void write_image(AtomicOutput& out, const render::Image& image, const RenderOptions& o, const render::ImageSettings& s,
                 const std::vector<std::pair<std::string, double>>& numbers, const std::string& scene) {
  H5::Exception::dontPrint();
  h5::MemoryFile memory;
  {
    H5::H5File& file = memory.file();
    h5::put_attr(file, "method", o.method);
    h5::put_attr(file, "spp", s.spp);
    h5::put_attr(file, "seed", std::int64_t(s.seed));
    h5::put_attr(file, "seconds", image.seconds);
    for (const auto& [name, value] : numbers) h5::put_attr(file, name.c_str(), value);
    if (!scene.empty()) h5::put_attr(file, "scene", scene);
    H5::Group g = file.createGroup("/image");
    std::vector<hsize_t> dims{hsize_t(image.height), hsize_t(image.width)};
    if (image.channels > 1) dims.push_back(hsize_t(image.channels));
    h5::put_dataset(g, "mean", dims, image.mean.data());
    h5::put_dataset(g, "variance_of_mean", dims, image.variance_of_mean.data());
  }
  out.stage(memory.bytes());
}

void add_render_command(CLI::App& app) {
  auto o = std::make_shared<RenderOptions>();
  CLI::App* cmd = app.add_subcommand(
      "render", "Render a scene file, or a sphere of medium under sky and sun, by brute force or through precomputed spheres");
  cmd->add_option("scene", o->scene, "Render scene (TOML: camera, light, media, objects); else the sphere of the medium flags")
      ->check(CLI::ExistingFile);
  add_medium_options(*cmd, o->medium, false);
  cmd->add_option("--width", o->width, "Image width in pixels")->capture_default_str();
  cmd->add_option("--height", o->height, "Image height in pixels")->capture_default_str();
  cmd->add_option("--spp", o->spp, "Camera paths per pixel (e.g. 64)")->required();
  cmd->add_option("--method", o->method, "brute: track every collision; stf: stride through precomputed spheres")
      ->required()
      ->check(CLI::IsMember({"brute", "stf"}));
  cmd->add_option("--pack", o->pack, "Pack with spheres of this medium (stf build); default: build one")
      ->check(CLI::ExistingFile);
  cmd->add_option("--tolerance", o->tolerance, "Without --pack: TV tolerance of the spheres built")
      ->capture_default_str();
  cmd->add_option("--model", o->model,
                  "Without --pack: the spheres' model, hvmf:auto or lvmf:auto (lifted lobes: strides without retries, "
                  "hvmf where they miss the tolerance; docs/render.md, \"Lifted lobes\")")
      ->capture_default_str();
  cmd->add_option("--cache", o->cache,
                  "Cache of the spheres built (default: $STF_CACHE_DIR, else $XDG_CACHE_HOME/stf or ~/.cache/stf)");
  cmd->add_option("--seed", o->seed, "Random seed; the same seed gives the same image for any --threads")
      ->capture_default_str();
  cmd->add_option("--threads", o->threads, "Worker threads (0: all cores)")->capture_default_str();
  cmd->add_option("-o,--output", o->output, "Output image (HDF5: /image/mean, /image/variance_of_mean)")->required();
  cmd->add_option("--exr", o->exr, "Also write the image as linear RGB OpenEXR");
  cmd->add_option("--png", o->png, "Also write the image as sRGB PNG, through a filmic tone curve");
  cmd->add_option("--exposure", o->exposure, "Exposure of the PNG in stops (radiance times 2^stops)")
      ->check(CLI::Range(-30.0, 30.0))
      ->capture_default_str();
  cmd->add_option("--json", o->json, "Write run statistics (seconds, collisions, strides) as JSON");
  cmd->add_flag("--quiet", o->quiet, "No progress bar and no summary line");
  cmd->add_flag("--ideal-strides", o->ideal_strides,
               "Scenes, --method stf: each stride the true transport through its sphere, its collisions counted apart "
               "(ideal_collisions): the bound no model can beat, for benches");
  cmd->add_option("--density-tolerance", o->density_tolerance,
                  "Scenes, --method stf: strides in a density grid take balls whose density varies by at most this "
                  "(max <= (1 + t) min; 0: constant only, exact up to the model; -1: no strides in grids)")
      ->check(CLI::Range(-1.0, 10.0))
      ->capture_default_str();
  cmd->add_option("--free-radius", o->free_radius,
                  "Scenes: a mesh's free radius from its distance grid (grid) or an exact Embree query (query)")
      ->check(CLI::IsMember({"grid", "query"}))
      ->capture_default_str();
  cmd->callback([o, cmd] {
    if (o->scene.empty()) return run_sphere_render(*o, *cmd);
    for (const char* flag : {"--sigma-s", "--sigma-a", "--g", "--radius"})
      if (cmd->count(flag)) fail(std::string(flag) + " belongs to the sphere: a scene file's media are in the file");
    run_scene_render(*o, *cmd);
  });
}

}  // namespace stf::cli
