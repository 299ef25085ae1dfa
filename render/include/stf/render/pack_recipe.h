// Which spheres a render precomputes: the one place that turns a render (a scene's objects, or
// the one-sphere form's medium) into the pack recipe `stf build` and `stf render` compute from.
#pragma once

#include <string>

#include "stf/core/table.h"
#include "stf/render/scene_geometry.h"
#include "stf/scene/render_scene.h"
#include "stf/scene/scene.h"

namespace stf::render {

// The spheres of one medium of `stf render`'s one-sphere form: render::pack_ladder's, computed
// with `settings` (scene::Settings' defaults are the renders' own).
scene::Scene sphere_pack_recipe(const Medium& m, scene::Settings settings);

// The spheres a scene's strides need: every object's medium in every channel (a grid's at its
// largest density), from the smallest sphere that pays to the largest that fits in the object
// (stride_ladder; the plan shares equal spheres), computed with `settings`. Media are named
// "NAME (R)", "NAME (G)", "NAME (B)".
scene::Scene scene_pack_recipe(const scene::RenderScene& scene, const SceneGeometry& geometry, scene::Settings settings);

// Where packs built for renders are cached: $STF_CACHE_DIR, else $XDG_CACHE_HOME/stf, else
// ~/.cache/stf; "" where none of them is set.
std::string default_cache_folder();

}  // namespace stf::render
