// The surfaces of a render scene (stf/scene/render_scene.h) placed and checked: its objects'
// boundaries (meshes through Embree, analytic spheres exactly), the ground plane, and each
// object's free radius at a point inside it: a lower bound of the distance to its boundary,
// from a distance grid (a load and a square root) or an exact Embree query.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "stf/core/parallel.h"
#include "stf/geometry/boundary.h"
#include "stf/geometry/distance_grid.h"
#include "stf/scene/render_scene.h"

namespace stf::render {

enum class FreeRadius { kGrid, kQuery };

inline constexpr int kGround = -2;  // SurfaceHit::object of the ground plane

struct SurfaceHit {
  bool found = false;
  double t = 0;
  int object = -1;  // index into the scene's objects, or kGround
  Vec3 normal;      // outward from the object; +y on the ground
};

class SceneGeometry {
 public:
  // Reads, checks and places the meshes; builds the distance grids (kGrid; `grid_cells` along
  // each object's largest side). Throws scene::SceneError naming the file, the object and what
  // is wrong (a mesh that cannot bound a medium, objects whose bounds overlap, an object below
  // the ground, the camera inside an object).
  SceneGeometry(const scene::RenderScene& scene, FreeRadius method, int grid_cells = 256, const RunContext& run = {});
  ~SceneGeometry();

  // The nearest surface along origin + t direction (unit), t in (0, t_max); the ground plane
  // only within 1e15 (farther it is the horizon, where a next ray's origin would leave the
  // range Embree traces in float). Debug builds assert that origin and direction are finite and
  // within that range (+-1.8e18) and the direction is not 0; NDEBUG compiles the check out.
  SurfaceHit trace(const Vec3& origin, const Vec3& direction, double t_max = HUGE_VAL) const;
  // From inside an analytic sphere object (nothing else lies inside one), where the ray leaves it
  // (found false only where rounding put the origin on or past its surface).
  SurfaceHit leave_sphere(const Vec3& origin, const Vec3& direction, int object) const;
  // A lower bound of the distance from x (inside `object`) to the object's boundary.
  double free_radius(const Vec3& x, int object) const;
  // A bound at least as large, dearer: the grid's eight-cell bound (the same as free_radius for
  // queries and spheres).
  double tight_free_radius(const Vec3& x, int object) const;
  // A point just off the surface at `point` (normal n) on the side `direction` heads for.
  Vec3 spawn(const Vec3& point, const Vec3& n, const Vec3& direction) const {
    return geometry::off_surface(point, n, direction, scale_);
  }

  int objects() const { return int(objects_.size()); }
  // An analytic sphere object's centre and radius; radius 0 where the object is a mesh. Nothing
  // else lies inside such a sphere (objects' bounds do not overlap, none reaches below the
  // ground): from inside, a straight segment leaves it exactly where its end lies outside.
  struct Ball {
    Vec3 centre;
    double radius = 0;
  };
  Ball sphere(int object) const {
    const Object& o = objects_[std::size_t(object)];
    return o.sphere ? Ball{o.centre, o.radius} : Ball{};
  }
  // The radius of the largest ball inside the object (from its distance grid or its sphere):
  // no stride sphere larger than this is ever used in it.
  double largest_free_radius(int object) const { return objects_[std::size_t(object)].inradius; }
  std::size_t grid_bytes() const;
  FreeRadius method() const { return method_; }

 private:
  struct Object {
    bool sphere = false;
    Vec3 centre;
    double radius = 0, inverse_radius = 0;
    int mesh = -1;  // index into the boundary's meshes
    geometry::Bounds bounds;
    double inradius = 0;
    std::unique_ptr<geometry::DistanceGrid> grid;
  };
  // The hit at t along the ray on sphere object `object`, its normal outward.
  SurfaceHit sphere_surface(const Vec3& origin, const Vec3& direction, double t, int object) const;
  void place_objects(const scene::RenderScene& scene);
  void check_layout(const scene::RenderScene& scene) const;
  std::vector<Object> objects_;
  std::vector<int> object_of_mesh_;
  std::unique_ptr<geometry::Boundary> boundary_;
  FreeRadius method_;
  bool ground_ = false;
  double ground_height_ = 0, scale_ = 1;
};

}  // namespace stf::render
