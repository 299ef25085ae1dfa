// `stf render SCENE.toml`: a render scene (media in meshes, in colour, behind glass, under a
// sun) by brute force or through shell strides, with the same next-event estimation.
#include <H5Cpp.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <filesystem>

#include "render_cmd.h"
#include "stf/core/h5io.h"
#include "stf/render/pack_recipe.h"
#include "stf/render/scene_geometry.h"
#include "stf/render/scene_paths.h"
#include "stf/scene/render_scene.h"

namespace stf::cli {

namespace {

nlohmann::ordered_json rays_by_kind(const render::Image& image) {
  nlohmann::ordered_json j;
  for (int k = 0; k < render::kRayKinds; ++k) j[render::kRayKindNames[k]] = image.rays_by[k];
  return j;
}

// The memory of the scene's density grids: values and majorant bricks.
std::size_t density_grid_bytes(const scene::RenderScene& sc) {
  std::size_t bytes = 0;
  for (const scene::MediumSpec& m : sc.media) bytes += m.grid ? m.grid->bytes() : 0;
  return bytes;
}

std::string scene_stats(const render::Image& image, const PackBuild& build, const render::SceneGeometry& geometry,
                        const scene::RenderScene& sc) {
  nlohmann::ordered_json j = {{"seconds", image.seconds},
                              {"precompute_seconds", build.seconds},
                              {"spheres_computed", build.spheres_computed},
                              {"paths", image.paths},
                              {"collisions", image.collisions},
                              {"null_collisions", image.null_collisions},
                              {"strides", image.strides},
                              {"distance_queries", image.distance_queries},
                              {"shadow_rays", image.shadow_rays},
                              {"rays", image.rays},
                              {"ideal_collisions", image.ideal_collisions},
                              {"once_scattered_exits", image.once_scattered_exits},
                              {"rays_by_kind", rays_by_kind(image)},
                              {"free_radius", geometry.method() == render::FreeRadius::kGrid ? "grid" : "query"},
                              {"grid_bytes", geometry.grid_bytes()},
                              {"density_grid_bytes", density_grid_bytes(sc)},
                              {"mean_radiance", {image.mean_radiance(0), image.mean_radiance(1), image.mean_radiance(2)}}};
  return j.dump(2) + "\n";
}

// The files a scene render reads: no output may be one of them.
std::vector<NamedFile> scene_inputs(const scene::RenderScene& sc) {
  std::vector<NamedFile> inputs{{sc.path, "the scene"}};
  if (!sc.light.environment.empty()) inputs.push_back({sc.light.environment, "light.environment"});
  for (std::size_t i = 0; i < sc.objects.size(); ++i)
    if (!sc.objects[i].mesh.empty()) inputs.push_back({sc.objects[i].mesh, fmt::format("objects[{}].mesh", i)});
  for (std::size_t i = 0; i < sc.media.size(); ++i)
    if (!sc.media[i].grid_file.empty()) inputs.push_back({sc.media[i].grid_file, fmt::format("media[{}].grid", i)});
  return inputs;
}

// "; N null collisions per real one" where delta tracking ran, else "".
std::string null_collision_words(const render::Image& image) {
  if (image.null_collisions == 0) return "";
  return fmt::format("; {:.3g} null collisions per real one", double(image.null_collisions) / double(std::max<std::int64_t>(1, image.collisions)));
}

bool any_spheres(const render::ScenePaths& paths, const scene::RenderScene& sc) {
  for (std::size_t i = 0; i < sc.objects.size(); ++i)
    for (int c = 0; c < 3; ++c)
      if (paths.spheres(int(i), c)) return true;
  return false;
}

}  // namespace

void run_scene_render(const RenderOptions& o, const CLI::App& cmd) {
  scene::RenderScene sc;
  try {
    sc = scene::read_render_scene(o.scene);
  } catch (const scene::SceneError& e) {
    fail(e.what());
  }
  render::ImageSettings s = image_settings(o, cmd, sc.camera.width, sc.camera.height);
  RenderOutputs outputs(o, scene_inputs(sc));
  const render::FreeRadius method = o.free_radius == "query" ? render::FreeRadius::kQuery : render::FreeRadius::kGrid;
  std::unique_ptr<render::SceneGeometry> geometry;
  try {
    geometry = std::make_unique<render::SceneGeometry>(sc, method, 256, RunContext{s.run.threads, &interrupted, {}});
  } catch (const scene::SceneError& e) {
    fail(e.what());
  }
  stop_if_interrupted();
  PackBuild build;
  std::vector<PackEntry> pack;
  if (o.method == "stf") {
    const scene::Scene needed = render::scene_pack_recipe(sc, *geometry, render_pack_settings(o));
    if (!o.pack.empty()) pack = read_pack_option(o.pack);
    else if (!needed.media.empty()) pack = build_pack(needed, o, s.run.threads, build);
  }
  if (o.ideal_strides && o.method != "stf") fail("--ideal-strides applies to --method stf only");
  render::PathOptions options;
  options.ideal_strides = o.ideal_strides, options.density_tolerance = o.density_tolerance;
  const render::ScenePaths paths(sc, *geometry, o.method == "stf" ? &pack : nullptr, options);
  if (!o.pack.empty() && !any_spheres(paths, sc))  // most likely the pack of other media
    fail("--pack: " + o.pack + " has no sphere of the albedo and g of any object's medium in any channel");
  ProgressBar bar("render", o.quiet);
  s.run.cancel = &interrupted, s.run.progress = bar.progress();
  const render::Image image = render::render(sc, paths, s);
  bar.finish();
  stop_if_interrupted();
  write_image(outputs.image, image, o, s, {}, std::filesystem::path(o.scene).filename().string());
  outputs.finish(image, o.exposure, scene_stats(image, build, *geometry, sc));
  if (!o.quiet)
    std::fprintf(stderr, "stf render: %s, %lld paths in %.3g s (%.3g collisions, %.3g strides per path%s%s), mean RGB %.4g %.4g %.4g -> %s\n",
                 o.method.c_str(), (long long)image.paths, image.seconds, double(image.collisions) / double(image.paths),
                 double(image.strides) / double(image.paths), null_collision_words(image).c_str(), precompute_words(build).c_str(), image.mean_radiance(0), image.mean_radiance(1),
                 image.mean_radiance(2), o.output.c_str());
}

}  // namespace stf::cli
