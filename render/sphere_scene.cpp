#include "stf/render/sphere_scene.h"

namespace stf::render {

scene::RenderScene sphere_scene(const Medium& m, int width, int height) {
  scene::RenderScene s;
  s.path = "stf render";
  s.camera.position = {0, 0, -kSphereCameraDistance * m.radius};
  s.camera.look_at = {0, 0, 0};
  s.camera.up = {0, 1, 0};
  s.camera.fov = kSphereFieldOfView;
  s.camera.width = width, s.camera.height = height;
  s.light.sky = {kSphereSky, kSphereSky, kSphereSky};
  // The sun is up and to the image's right: the scene camera's frame is right-handed, so looking
  // along +z, the image's right is -x.
  s.light.sun_direction = normalize(Vec3{-1, 1, -1});
  const double sun = kSphereSun - kSphereSky;  // a scene's sun adds to its sky
  s.light.sun = {sun, sun, sun};
  s.light.sun_angle = kSphereSunHalfAngle;
  scene::MediumSpec medium;
  medium.name = "sphere";
  medium.sigma_s.fill(m.sigma_s), medium.sigma_a.fill(m.sigma_a), medium.g.fill(m.g);
  s.media.push_back(medium);
  scene::ObjectSpec o;
  o.radius = m.radius;
  s.objects.push_back(o);
  return s;
}

}  // namespace stf::render
