// The scene file: the media a renderer will use and how to precompute for them (TOML).
//
//   [settings]                 (all optional; docs/scenes.md, "Pack recipe")
//   paths = 4e6                paths per precomputed table
//   grid = "healpix:16"        direction cells
//   alpha_bins = 45
//   model = "hvmf:auto"        fit model
//   seed = 1
//   tau_skip = 2.0             media whose largest optical radius is below this are skipped
//   tau_ratio = 2.0            ratio between neighbouring optical radii of a medium's family
//   tolerance = 0.1            target TV distance of each entry's exit distribution; with it,
//                              paths, grid, alpha_bins and the model's size are upper limits
//                              and each entry gets the least that is certified within it
//                              (stf/measure/tolerance.h; paths in rounds, fourfold each)
//
//   [[media]]
//   name = "milk"
//   sigma_s = 50.0             scattering coefficient (1 / scene unit)
//   sigma_a = 0.02             absorption coefficient
//   g = 0.8                    Henyey-Greenstein asymmetry
//   radius_min = 0.01          radii of the spheres a renderer will place in it, or instead
//   radius_max = 0.5           size = 1.0 (the object's size: radius_max = size / 2,
//                              radius_min = radius_max / 64)
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "stf/scene/scene_error.h"

namespace stf::scene {

// The defaults are `stf render`'s: what a render precomputes and what a recipe gets unless it
// says otherwise (render/pack_recipe.h).
struct Settings {
  std::int64_t paths = 4'000'000;
  std::string grid = "healpix:16";
  int alpha_bins = 45;
  std::string model = "hvmf:auto";
  std::int64_t seed = 1;
  double tau_skip = 2;
  double tau_ratio = 2;
  double tolerance = 0;  // 0: none; paths, grid, alpha_bins and model are used as given
};

struct Medium {
  std::string name;
  double sigma_s = 0, sigma_a = 0, g = 0;
  double radius_min = 0, radius_max = 0;
  int line = 0;  // where it is defined
};

struct Scene {
  std::string path;
  Settings settings;
  std::vector<Medium> media;
};

Scene read_scene(const std::string& path);

}  // namespace stf::scene
