#include "stf/render/pack_recipe.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "stf/render/ladder.h"

namespace stf::render {

namespace {

const char* const kChannel[3] = {"R", "G", "B"};

}  // namespace

scene::Scene sphere_pack_recipe(const Medium& m, scene::Settings settings) {
  scene::Scene sc;
  sc.path = "stf render";
  sc.settings = settings;
  const PackLadder ladder = pack_ladder(m);
  sc.settings.tau_skip = ladder.smallest;
  sc.settings.tau_ratio = ladder.ratio;
  sc.media.push_back({"render", m.sigma_s, m.sigma_a, m.g, ladder.radius_min, ladder.radius_max, 0});
  return sc;
}

scene::Scene scene_pack_recipe(const scene::RenderScene& sc, const SceneGeometry& geometry, scene::Settings settings) {
  scene::Scene pack;
  pack.path = sc.path;
  pack.settings = settings;
  pack.settings.tau_skip = HUGE_VAL;
  for (std::size_t i = 0; i < sc.objects.size(); ++i) {
    const scene::MediumSpec& m = sc.media[std::size_t(sc.objects[i].medium)];
    // A grid's spheres: the ladder at its densest (a sphere of optical radius tau serves every
    // density, at radius tau / sigma_t).
    const double density = m.grid ? m.grid->max_density() : 1.0;
    for (std::size_t c = 0; c < 3; ++c) {
      const Medium channel{density * m.sigma_s[c], density * m.sigma_a[c], m.g[c], 1};
      const PackLadder l = stride_ladder(channel, geometry.largest_free_radius(int(i)));
      if (l.radius_max < l.radius_min) continue;
      pack.settings.tau_skip = std::min(pack.settings.tau_skip, l.smallest);
      pack.settings.tau_ratio = l.ratio;
      pack.media.push_back({fmt::format("{} ({})", m.name, kChannel[c]), channel.sigma_s, channel.sigma_a, channel.g,
                            l.radius_min, l.radius_max, sc.objects[i].line});
    }
  }
  return pack;
}

std::string default_cache_folder() {
  if (const char* d = std::getenv("STF_CACHE_DIR"); d && *d) return d;
  if (const char* d = std::getenv("XDG_CACHE_HOME"); d && *d) return std::string(d) + "/stf";
  if (const char* d = std::getenv("HOME"); d && *d) return std::string(d) + "/.cache/stf";
  return "";
}

}  // namespace stf::render
