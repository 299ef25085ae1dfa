// What `stf render`'s two forms share: the sphere of flags (render_cmd.cpp) and a scene file
// (render_scene_cmd.cpp) parse the same options, build or read the same kind of pack and write
// the same outputs.
#pragma once

#include <CLI/CLI.hpp>

#include <optional>
#include <string>
#include <vector>

#include <stf/pack.h>

#include "cli.h"
#include "stf/core/table.h"
#include "stf/render/render.h"
#include "stf/render/scene_paths.h"
#include "stf/scene/scene.h"

namespace stf::cli {

struct RenderOptions {
  std::string scene;  // a render scene file, or "" for the sphere of the medium flags
  Medium medium;
  std::string width = "64", height = "64", spp, seed = "1", threads = "0";
  std::string method, pack, cache, output, exr, png, json, free_radius = "grid";
  double tolerance = 0.02, exposure = 0;
  double density_tolerance = render::kDensityTolerance;  // strides in density grids
  std::string model = "hvmf:auto";  // the spheres' model family (a fitter's --model)
  bool quiet = false, ideal_strides = false;
};

// What building the render's pack took: its seconds, and how many spheres were walked and fitted
// (the others came from the cache).
struct PackBuild {
  double seconds = 0;
  int spheres_computed = 0;
};

// Every output claimed before any work; none may be the pack, one of `inputs` (the scene, its
// meshes and environment map) or another output.
struct RenderOutputs {
  explicit RenderOutputs(const RenderOptions& o, std::vector<NamedFile> inputs = {});
  AtomicOutput image;
  std::optional<AtomicOutput> exr, png, json;
  // Writes the EXR and PNG of `image`, stages `json` and puts everything in place together.
  void finish(const render::Image& image, double exposure, const std::string& json_text);
};

// --spp, --seed, --threads, and --width/--height (else the given defaults); checks the options
// both forms share.
render::ImageSettings image_settings(const RenderOptions& o, const CLI::App& cmd, int width, int height);

// Builds (or finds in the cache) the pack of `scene`'s media (certified within --tolerance);
// returns its entries, and in `build` what building took.
std::vector<PackEntry> build_pack(const scene::Scene& scene, const RenderOptions& o, int threads, PackBuild& build);
std::vector<PackEntry> read_pack_option(const std::string& path);
// "; precompute S s, N spheres computed" for the summary line; "" where no pack was built.
std::string precompute_words(const PackBuild& build);

// The settings of the packs renders build: scene::Settings' defaults with --tolerance and --model.
scene::Settings render_pack_settings(const RenderOptions& o);

void run_scene_render(const RenderOptions& o, const CLI::App& cmd);

// The image as HDF5 (docs/formats.md, "Image"): /image/mean and /image/variance_of_mean, [H, W]
// for one channel or [H, W, 3]; root attributes method, spp, seed, seconds, then `numbers` and,
// where given, `scene` (the scene file's name).
void write_image(AtomicOutput& out, const render::Image& image, const RenderOptions& o, const render::ImageSettings& s,
                 const std::vector<std::pair<std::string, double>>& numbers, const std::string& scene = "");

}  // namespace stf::cli
