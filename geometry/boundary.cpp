#include "stf/geometry/boundary.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace stf::geometry {

struct Boundary::Embree {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  ~Embree() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

namespace {

void check(RTCDevice device, const char* what) {
  if (const RTCError e = rtcGetDeviceError(device); e != RTC_ERROR_NONE)
    throw std::runtime_error(std::string("Embree: ") + what + " failed (error " + std::to_string(int(e)) + ")");
}

void attach(RTCDevice device, RTCScene scene, const TriangleMesh& mesh, unsigned id) {
  RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<float*>(
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.vertices.size()));
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i)
    v[3 * i] = float(mesh.vertices[i].x), v[3 * i + 1] = float(mesh.vertices[i].y), v[3 * i + 2] = float(mesh.vertices[i].z);
  auto* t = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), mesh.triangles.size()));
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i)
    for (std::size_t j = 0; j < 3; ++j) t[3 * i + j] = mesh.triangles[i][j];
  rtcCommitGeometry(g);
  rtcAttachGeometryByID(scene, g, id);
  rtcReleaseGeometry(g);
}

// The nearest triangle so far of a point query, in double precision on the meshes' vertices.
struct Nearest {
  const std::vector<TriangleMesh>* meshes;
  Vec3 x;
  double squared = HUGE_VAL;
};

bool closer_triangle(RTCPointQueryFunctionArguments* args) {
  auto* n = static_cast<Nearest*>(args->userPtr);
  const TriangleMesh& m = (*n->meshes)[args->geomID];
  const auto& t = m.triangles[args->primID];
  const double d2 = squared_distance_to_triangle(n->x, m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]]);
  if (!(d2 < n->squared)) return false;
  n->squared = d2;
  // Shrinks the search to this distance, rounded up so that no triangle as near is culled.
  args->query->radius = std::nextafter(float(std::sqrt(d2)), HUGE_VALF);
  return true;
}

Vec3 to_vec(float x, float y, float z) { return {x, y, z}; }

}  // namespace

Boundary::Boundary(std::vector<TriangleMesh> meshes) : meshes_(std::move(meshes)), embree_(std::make_unique<Embree>()) {
  embree_->device = rtcNewDevice(nullptr);
  if (!embree_->device) throw std::runtime_error("Embree: no device (error " + std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
  embree_->scene = rtcNewScene(embree_->device);
  rtcSetSceneFlags(embree_->scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(embree_->scene, RTC_BUILD_QUALITY_HIGH);
  for (std::size_t k = 0; k < meshes_.size(); ++k) {
    attach(embree_->device, embree_->scene, meshes_[k], unsigned(k));
    scale_ = std::max(scale_, bounds_of(meshes_[k]).largest_side());
  }
  rtcCommitScene(embree_->scene);
  check(embree_->device, "building the scene");
}

Boundary::~Boundary() = default;

Hit Boundary::intersect(const Vec3& origin, const Vec3& direction, double t_max) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh{};
  rh.ray.org_x = float(origin.x), rh.ray.org_y = float(origin.y), rh.ray.org_z = float(origin.z);
  rh.ray.dir_x = float(direction.x), rh.ray.dir_y = float(direction.y), rh.ray.dir_z = float(direction.z);
  rh.ray.tnear = 0;
  rh.ray.tfar = t_max < 3e38 ? float(t_max) : HUGE_VALF;
  rh.ray.mask = ~0u;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(embree_->scene, &context, &rh);
  Hit h;
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return h;
  h.found = true, h.t = rh.ray.tfar, h.object = int(rh.hit.geomID), h.triangle = int(rh.hit.primID);
  const TriangleMesh& m = meshes_[rh.hit.geomID];
  const auto& t = m.triangles[rh.hit.primID];
  h.normal = normalize(cross(m.vertices[t[1]] - m.vertices[t[0]], m.vertices[t[2]] - m.vertices[t[0]]));
  return h;
}

double Boundary::distance(const Vec3& x) const {
  RTCPointQuery query;
  query.x = float(x.x), query.y = float(x.y), query.z = float(x.z);
  query.time = 0;
  query.radius = HUGE_VALF;
  RTCPointQueryContext context;
  rtcInitPointQueryContext(&context);
  Nearest nearest{&meshes_, x};
  rtcPointQuery(embree_->scene, &query, &context, closer_triangle, &nearest);
  // Embree searches about x rounded to float and culls boxes in float: the margin covers both.
  const double moved = length(x - to_vec(query.x, query.y, query.z));
  return std::max(0.0, std::sqrt(nearest.squared) * (1 - 2e-6) - moved);
}

bool Boundary::inside(const Vec3& x, int object) const {
  // A direction no mesh edge is likely to lie along.
  const Vec3 d = normalize({0.5427, 0.7261, 0.4223});
  int crossings = 0;
  Vec3 from = x;
  for (Hit h = intersect(from, d); h.found; h = intersect(from, d)) {
    crossings += h.object == object;
    from = spawn(from + h.t * d, h.normal, d);
  }
  return crossings % 2 == 1;
}

Vec3 Boundary::spawn(const Vec3& point, const Vec3& n, const Vec3& direction) const {
  return off_surface(point, n, direction, scale_);
}

double squared_distance_to_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  // The nearest point by the Voronoi regions of the vertices, then edges, then the face.
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return dot(ap, ap);
  const Vec3 bp = p - b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return dot(bp, bp);
  const Vec3 cp = p - c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return dot(cp, cp);
  const double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
  Vec3 nearest;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) nearest = a + (d1 / (d1 - d3)) * ab;
  else if (vb <= 0 && d2 >= 0 && d6 <= 0) nearest = a + (d2 / (d2 - d6)) * ac;
  else if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) nearest = b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  else nearest = a + (vb / (va + vb + vc)) * ab + (vc / (va + vb + vc)) * ac;
  const Vec3 e = p - nearest;
  return dot(e, e);
}

}  // namespace stf::geometry
