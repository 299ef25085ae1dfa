// The camera rays of `stf render`'s one-sphere scene (stf/render/sphere_scene.h) where they enter
// the sphere: the start of the benches' own reference loops through that scene.
#pragma once

#include "stf/render/render.h"
#include "stf/render/scene_geometry.h"
#include "stf/render/sphere_scene.h"

namespace bench {

// The rays of a 64 x 64 image of the sphere of `m`.
class SphereCamera {
 public:
  explicit SphereCamera(const stf::Medium& m)
      : scene_(stf::render::sphere_scene(m, 64, 64)), geometry_(scene_, stf::render::FreeRadius::kQuery) {}
  // The ray through image position (px, py): false when it misses the sphere, else its entry
  // point and direction.
  bool enter(double px, double py, stf::Vec3& entry, stf::Vec3& direction) const {
    const stf::render::Ray ray = stf::render::camera_ray(scene_.camera, px, py, 64, 64);
    const stf::render::SurfaceHit hit = geometry_.trace(ray.origin, ray.direction);
    if (!hit.found) return false;
    entry = ray.origin + hit.t * ray.direction, direction = ray.direction;
    return true;
  }

 private:
  stf::scene::RenderScene scene_;
  stf::render::SceneGeometry geometry_;
};

}  // namespace bench
