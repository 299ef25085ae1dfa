// The one-sphere form of `stf render` as a render scene: a sphere of homogeneous medium at the
// origin (index matched, so paths cross its boundary unbent), a pinhole camera on the -z axis
// four radii away, a uniform sky of radiance 1 and a small sun of radiance 50 (docs/render.md).
// It renders through the scene path loop (ScenePaths) like any scene file, in one channel.
#pragma once

#include "stf/core/table.h"
#include "stf/scene/render_scene.h"

namespace stf::render {

inline constexpr double kSphereSky = 1;
inline constexpr double kSphereSun = 50;  // within the sun's disc, the sky's included
inline constexpr double kSphereSunHalfAngle = 5;  // degrees
inline constexpr double kSphereFieldOfView = 40;  // vertical, degrees
inline constexpr double kSphereCameraDistance = 4;  // in sphere radii

// The scene of `m` (its sigma_s, sigma_a and g in every channel; its radius the sphere's) seen in
// a width x height image.
scene::RenderScene sphere_scene(const Medium& m, int width, int height);

}  // namespace stf::render
