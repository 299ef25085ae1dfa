#include "stf/render/scene_geometry.h"

#include <fmt/format.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>

#include "stf/core/reading_input.h"
#include "stf/scene/scene_error.h"

namespace stf::render {

namespace {

using geometry::Bounds;

// The largest coordinate of a ray Embree traces (its FLT_LARGE, in float).
[[maybe_unused]] constexpr double kEmbreeLargest = 1.844e18;
// How far along a ray the ground plane is met at most (where the ray's origin is within the
// scene's +-kLargestCoordinate, its hit stays well within kEmbreeLargest).
constexpr double kFarthestGround = 1e15;

[[noreturn]] void refuse(const scene::RenderScene& s, int line, const std::string& what) {
  throw scene::SceneError(s.path + ":" + std::to_string(line) + ": " + what);
}

// "objects[i]", with the mesh's file where it has one: a layout refusal may come from the mesh.
std::string object_name(const scene::RenderScene& s, std::size_t i) {
  const std::string mesh = s.objects[i].mesh;
  return fmt::format("objects[{}]", i) + (mesh.empty() ? "" : " (" + mesh + ")");
}

// The first vertex placed beyond kLargestCoordinate, or "".
std::string placement_error(const geometry::TriangleMesh& mesh) {
  for (const Vec3& v : mesh.vertices)
    if (!(std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}) <= scene::kLargestCoordinate))
      return fmt::format("scale and translate place a vertex at ({:g}, {:g}, {:g}), beyond +-{:g} (surfaces are traced in float)",
                         v.x, v.y, v.z, scene::kLargestCoordinate);
  return "";
}

// The object's mesh read, placed and checked as Embree will trace it (in float, where a
// triangle may collapse).
geometry::TriangleMesh load_mesh(const scene::RenderScene& s, std::size_t i) {
  const scene::ObjectSpec& o = s.objects[i];
  const std::string where = "objects[" + std::to_string(i) + (o.box ? "] (its grid's box): " : "].mesh: ");
  geometry::TriangleMesh mesh;
  try {
    const geometry::TriangleMesh unplaced = o.box ? geometry::box(o.box_bounds.lower, o.box_bounds.upper) : geometry::read_obj(o.mesh);
    mesh = geometry::placed(unplaced, o.scale, o.translate);
  } catch (const std::runtime_error& e) {
    refuse(s, o.line, where + e.what());
  }
  std::string why = placement_error(mesh);
  if (why.empty()) why = geometry::mesh_error(mesh);
  if (!why.empty()) refuse(s, o.line, where + (o.box ? "" : o.mesh + ": ") + why);
  return geometry::oriented_outward(std::move(mesh));
}

bool overlap(const Bounds& a, const Bounds& b) {
  return a.lower.x < b.upper.x && b.lower.x < a.upper.x && a.lower.y < b.upper.y && b.lower.y < a.upper.y &&
         a.lower.z < b.upper.z && b.lower.z < a.upper.z;
}

bool contains(const Bounds& b, const Vec3& p) {
  return p.x >= b.lower.x && p.x <= b.upper.x && p.y >= b.lower.y && p.y <= b.upper.y && p.z >= b.lower.z && p.z <= b.upper.z;
}

// The sphere's entry or exit along the ray: the first root above 0 of |o + t d - c| = r.
double sphere_hit(const Vec3& o, const Vec3& d, const Vec3& c, double r) {
  const Vec3 oc = o - c;
  const double b = dot(oc, d), q = dot(oc, oc) - r * r, disc = b * b - q;
  if (disc < 0 || (q > 0 && b > 0)) return HUGE_VAL;  // misses, or starts outside heading away
  const double root = std::sqrt(disc), near = -b - root, far = -b + root;
  return near > 0 ? near : (far > 0 ? far : HUGE_VAL);
}

#ifndef NDEBUG
// Whether Embree can trace the ray: its origin and direction finite and, as floats, within the
// +-1.8e18 its ray.valid() asserts (FLT_LARGE); the direction not 0.
bool traceable(const Vec3& origin, const Vec3& direction) {
  for (const double v : {origin.x, origin.y, origin.z, direction.x, direction.y, direction.z})
    if (!(std::abs(v) <= kEmbreeLargest)) return false;
  return dot(direction, direction) > 0;
}
#endif

// Debug builds stop at a ray Embree could not trace, naming it; NDEBUG compiles the check out.
void check_ray([[maybe_unused]] const Vec3& origin, [[maybe_unused]] const Vec3& direction) {
#ifndef NDEBUG
  if (traceable(origin, direction)) return;
  std::fprintf(stderr, "stf: a ray from (%g, %g, %g) heading (%g, %g, %g) cannot be traced\n", origin.x, origin.y,
               origin.z, direction.x, direction.y, direction.z);
  assert(!"SceneGeometry::trace: a ray's origin and direction must be finite and within +-1.8e18, its direction not 0");
#endif
}

}  // namespace

SceneGeometry::SceneGeometry(const scene::RenderScene& s, FreeRadius method, int grid_cells, const RunContext& run)
    : method_(method), ground_(s.ground.present), ground_height_(s.ground.height) {
  place_objects(s);
  check_layout(s);
  for (Object& o : objects_) {
    if (o.sphere) continue;
    o.grid = std::make_unique<geometry::DistanceGrid>(*boundary_, o.bounds, grid_cells, run);
    if (run.cancelled()) return;  // a partial grid: the caller stops
    o.inradius = o.grid->deepest(*boundary_, o.mesh);
  }
}

SceneGeometry::~SceneGeometry() = default;

void SceneGeometry::place_objects(const scene::RenderScene& s) {
  // Reading millions of triangles and building Embree's tree take seconds: until they are done
  // a first Ctrl-C ends the command at once (nothing is written yet). The grids poll for it.
  const h5::ReadingInput reading;
  std::vector<geometry::TriangleMesh> meshes;
  for (std::size_t i = 0; i < s.objects.size(); ++i) {
    const scene::ObjectSpec& o = s.objects[i];
    Object obj;
    if (o.mesh.empty() && !o.box) {
      obj.sphere = true, obj.centre = o.translate, obj.radius = o.radius * o.scale, obj.inradius = obj.radius;
      obj.inverse_radius = 1 / obj.radius;
      const Vec3 r{obj.radius, obj.radius, obj.radius};
      obj.bounds = {obj.centre - r, obj.centre + r};
    } else {
      meshes.push_back(load_mesh(s, i));
      obj.mesh = int(meshes.size()) - 1, obj.bounds = geometry::bounds_of(meshes.back());
      object_of_mesh_.push_back(int(i));
    }
    scale_ = std::max(scale_, obj.bounds.largest_side());
    objects_.push_back(std::move(obj));
  }
  boundary_ = std::make_unique<geometry::Boundary>(std::move(meshes));
}

void SceneGeometry::check_layout(const scene::RenderScene& s) const {
  for (std::size_t i = 0; i < objects_.size(); ++i) {
    const Bounds& b = objects_[i].bounds;
    for (std::size_t j = 0; j < i; ++j)
      if (overlap(b, objects_[j].bounds))
        refuse(s, s.objects[i].line, fmt::format("{}: its bounds overlap those of {}; media must not overlap", object_name(s, i), object_name(s, j)));
    if (ground_ && b.lower.y < ground_height_)
      refuse(s, s.objects[i].line, fmt::format("{}: reaches below the ground (y = {:g})", object_name(s, i), ground_height_));
    if (contains(b, s.camera.position) && (objects_[i].sphere ? length(s.camera.position - objects_[i].centre) < objects_[i].radius
                                                              : boundary_->inside(s.camera.position, objects_[i].mesh)))
      refuse(s, s.objects[i].line, fmt::format("{}: the camera is inside it", object_name(s, i)));
  }
  if (ground_ && s.camera.position.y <= ground_height_) refuse(s, 1, "camera.position: below the ground");
}

SurfaceHit SceneGeometry::trace(const Vec3& origin, const Vec3& direction, double t_max) const {
  check_ray(origin, direction);
  SurfaceHit best;
  best.t = t_max;
  if (!object_of_mesh_.empty()) {  // no meshes (spheres only): no call into Embree at all
    const geometry::Hit h = boundary_->intersect(origin, direction, t_max);
    if (h.found) best = {true, h.t, object_of_mesh_[std::size_t(h.object)], h.normal};
  }
  for (std::size_t i = 0; i < objects_.size(); ++i) {
    if (!objects_[i].sphere) continue;
    const double t = sphere_hit(origin, direction, objects_[i].centre, objects_[i].radius);
    if (t < best.t) best = sphere_surface(origin, direction, t, int(i));
  }
  if (ground_ && direction.y < 0) {
    const double t = (ground_height_ - origin.y) / direction.y;
    // A ray that skims the plane meets it at the horizon, as far as 1 / |direction.y|: there a
    // next ray's origin could leave float's range (1e-300 puts it at 1e300). The ground ends
    // at kFarthestGround, far beyond any scene (coordinates within kLargestCoordinate).
    if (t > 0 && t < best.t && t <= kFarthestGround) best = {true, t, kGround, {0, 1, 0}};
  }
  return best;
}

SurfaceHit SceneGeometry::leave_sphere(const Vec3& origin, const Vec3& direction, int object) const {
  const Object& o = objects_[std::size_t(object)];
  const double t = sphere_hit(origin, direction, o.centre, o.radius);
  return t < HUGE_VAL ? sphere_surface(origin, direction, t, object) : SurfaceHit{};
}

SurfaceHit SceneGeometry::sphere_surface(const Vec3& origin, const Vec3& direction, double t, int object) const {
  const Object& o = objects_[std::size_t(object)];
  return {true, t, object, (origin + t * direction - o.centre) * o.inverse_radius};  // |p - c| = r: no square root
}

double SceneGeometry::free_radius(const Vec3& x, int object) const {
  const Object& o = objects_[std::size_t(object)];
  if (o.sphere) return std::max(0.0, o.radius - length(x - o.centre));
  return method_ == FreeRadius::kGrid ? o.grid->lower_bound(x) : boundary_->distance(x);
}

double SceneGeometry::tight_free_radius(const Vec3& x, int object) const {
  const Object& o = objects_[std::size_t(object)];
  return o.grid && method_ == FreeRadius::kGrid ? o.grid->tight_lower_bound(x) : free_radius(x, object);
}

std::size_t SceneGeometry::grid_bytes() const {
  std::size_t bytes = 0;
  for (const Object& o : objects_) bytes += o.grid ? o.grid->bytes() : 0;
  return bytes;
}

}  // namespace stf::render
