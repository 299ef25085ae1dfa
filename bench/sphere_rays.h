// The camera rays of `stf render`'s one-sphere scene (stf/render/sphere_scene.h) where they enter
// the sphere: the start of the benches' own reference loops through that scene.
#pragma once

#include <cmath>

#include "stf/render/render.h"
#include "stf/render/sphere_scene.h"

namespace bench {

// The rays of a 64 x 64 image of the sphere of `m`.
class SphereCamera {
 public:
  explicit SphereCamera(const stf::Medium& m) : radius_(m.radius), camera_(stf::render::sphere_scene(m, 64, 64).camera) {}
  // The ray through image position (px, py): false when it misses the sphere, else its entry
  // point and direction.
  bool enter(double px, double py, stf::Vec3& entry, stf::Vec3& direction) const {
    const stf::render::Ray ray = stf::render::camera_ray(camera_, px, py, 64, 64);
    const double b = stf::dot(ray.origin, ray.direction), c = stf::dot(ray.origin, ray.origin) - radius_ * radius_;
    const double disc = b * b - c;
    if (disc <= 0 || b >= 0) return false;
    entry = ray.origin + (-b - std::sqrt(disc)) * ray.direction, direction = ray.direction;
    return true;
  }

 private:
  double radius_;
  stf::scene::CameraSpec camera_;
};

}  // namespace bench
