// Camera paths through a render scene, by brute force (every collision tracked) or in shell
// strides (spheres of a pack wherever one fits inside the object's medium, collisions only in
// the boundary shell), with the same geometry, boundaries, lights and next-event estimation:
//  - each path carries one colour channel, whose medium coefficients it sees;
//  - at every collision it tracks and at every ground hit, a shadow ray toward a point of the
//    sun's disc (and, with an environment map, one toward a direction drawn from the map), with
//    the transmittance of the index-matched media it crosses (zero through a dielectric
//    boundary or the ground), combined with the phase function's (or the ground's cosine)
//    direction by the power heuristic; at a stride's smooth exit the same, the exit's direction
//    density (ShellSampler::exit_direction_pdf) in the phase function's place; after a
//    once-scattered exit none (its directions have no density), its direction then picking
//    up the sun and the map with weight 1;
//  - deep inside a medium the shadow ray plays Russian roulette against the transmittance bound
//    exp(-sigma_t free_radius), so brute force does not pay for rays that carry nothing.
#pragma once

#include <memory>
#include <vector>

#include <stf/lookup.h>
#include <stf/pack.h>

#include "stf/hg.h"
#include "stf/render/environment.h"
#include "stf/render/medium.h"
#include "stf/render/pixel_rng.h"
#include "stf/render/scene_geometry.h"
#include "stf/render/path_counters.h"

namespace stf::render {

// The default tolerance of strides in density grids (docs/render.md, "Strides through media that
// vary": its bias, measured).
inline constexpr double kDensityTolerance = 0.5;

// How ScenePaths follows paths beyond what the scene says.
struct PathOptions {
  // false: no shadow rays, the sun found only by paths that leave toward it (the same image,
  // noisier: the tests compare the two).
  bool next_event = true;
  // true: every stride is the true transport through its sphere, a walk whose collisions are
  // counted apart (PathCounters::ideal_collisions): the strides no model can beat, whose shell
  // collisions and strides per path bound what any stride cost can give (bench/scene_bench.py).
  bool ideal_strides = false;
  // false: a path from a stride's exit that meets a light takes it at weight 1 though a shadow
  // ray was cast there, counting the light twice; for the test that shows the MIS weight at
  // exits is what keeps the image right.
  bool exit_mis = true;
  // In a density grid, strides take balls over which the density varies by at most this
  // (max <= (1 + tolerance) min); 0: only where it is constant (exact up to the model); below 0:
  // no strides in grids.
  double density_tolerance = kDensityTolerance;
};

struct PathState;  // a path on its way (path_state.h)

class ScenePaths {
 public:
  // Brute force without `pack`; strides through the pack's spheres of each channel's albedo and
  // g otherwise (a channel without any is tracked by collisions).
  ScenePaths(const scene::RenderScene& scene, const SceneGeometry& geometry, const std::vector<PackEntry>* pack = nullptr,
             PathOptions options = {});
  ~ScenePaths();

  // The radiance of `channel` arriving at `origin` from direction -`direction`.
  double radiance(const Vec3& origin, const Vec3& direction, int channel, PixelRng& rng, PathCounters& counters) const;

  // What a path in `object` sees in `channel`: homogeneous, or the object's density grid.
  const ChannelMedium& medium(int object, int channel) const { return media_[std::size_t(object * 3 + channel)]; }
  // The spheres a path in `object` strides through in `channel` (null: none).
  const SphereLookup* spheres(int object, int channel) const { return lookups_[std::size_t(object * 3 + channel)].get(); }

 private:
  using State = PathState;
  double escape(const State& s, int c) const;
  // A direction toward a uniform point of the sun's disc (density sun_pdf_ per sr).
  Vec3 toward_sun(PixelRng& rng) const;
  double transmittance(Vec3 x, const Vec3& l, int c, RayKind kind, PixelRng& rng, PathCounters& counters) const;
  // A vertex that casts shadow rays: its path's channel, what its rays count as, a bound on the
  // transmittance from it toward any light (exp(-sigma_t free radius) in a medium), and the
  // uniform that decides its rays (may_cast).
  struct ShadowVertex {
    int channel;
    RayKind kind;
    double most, u;
  };
  // The uniform that decides a vertex's shadow rays, and the least optical depth from the vertex
  // toward any light (its transmittance bound, most, is exp(-depth)).
  struct ShadowOdds {
    double u = 0, depth = 0;
  };
  // Whether a collision at x, free radius `bound`, in medium m may cast shadow rays, drawing the
  // uniform that decides them (none behind a dielectric, where no shadow ray passes).
  bool may_light(const State& s, const Vec3& x, const ChannelMedium& m, double bound, ShadowOdds& odds, PixelRng& rng) const;
  // A tighter bound on the gain of a collision's shadow rays: its phase density at the sun's
  // disc over the disc's density (no map), else 1/2.
  double collision_gain_bound(const ChannelMedium& m, const Vec3& w) const;
  // What shadow rays from a vertex bring: one toward a uniform point of the sun's disc and, with
  // a map, one toward a direction drawn from it, each weighted by the power heuristic against
  // the vertex's own density(l) of scattering into l, each cast or not by Russian roulette
  // against the most it could bring (kShadowRoulette); start(l) is where the ray toward l starts.
  template <typename Density, typename Start>
  double direct(const ShadowVertex& v, PixelRng& rng, PathCounters& counters, const Density& density,
                const Start& start) const;
  // A direction toward a light, its density per sr and the light's radiance along it.
  struct LightSample {
    Vec3 l;
    double pdf = 0, radiance = 0;
  };
  template <typename Density, typename Start>
  double light_ray(const LightSample& light, const ShadowVertex& v, PixelRng& rng, PathCounters& counters,
                   const Density& density, const Start& start) const;
  void nee_at_collision(State& s, int c, const ShadowOdds& odds, PixelRng& rng, PathCounters& counters) const;
  // At a stride's smooth exit in an index-matched medium (State::exit set): shadow rays weighted
  // by the exit's direction density, the free radius at the exit found for them and for the
  // next step.
  void nee_at_exit(State& s, int c, PixelRng& rng, PathCounters& counters) const;
  bool ground_bounce(State& s, int c, const SurfaceHit& h, PixelRng& rng, PathCounters& counters) const;
  void cross(State& s, const SurfaceHit& h, PixelRng& rng) const;
  bool medium_step(State& s, int c, PixelRng& rng, PathCounters& counters) const;
  // A real collision after a flight of t: the albedo, the free radius carried or refreshed, shadow
  // rays, and a new direction from the phase function.
  void collide(State& s, int c, const ChannelMedium& m, double t, PixelRng& rng, PathCounters& counters) const;
  // The direction on from w at a collision, drawn from the phase function; the path keeps the
  // cosine its density needs where it later meets a light.
  Vec3 scatter(State& s, const ChannelMedium& m, const Vec3& w, PixelRng& rng) const;
  // Inside an analytic sphere of homogeneous medium nothing else lies (SceneGeometry::sphere):
  // a flight leaves where its end lies outside, and a pack's sphere of radius r fits about x
  // where |x - centre|^2 <= (R - r)^2. Its steps need no free radius and cast no flight ray.
  struct SphereRoom {
    Vec3 centre;
    double radius = 0, radius2 = 0;  // radius 0: the object is not such a sphere
    // The scene's only object, no ground, index matched: a path leaving it meets nothing more,
    // so it escapes at once (no exit point, no ray after it).
    bool alone = false;
    std::vector<double> limit2, stride_radius;  // per sphere of the lookup, limit2 descending
    // The largest sphere of the lookup that fits at squared distance d2 from the centre, or -1.
    int fitting(double d2) const {
      int k = -1;
      for (double limit : limit2) k += d2 <= limit;  // the fitting ones are a prefix: no branch
      return k;
    }
  };
  // What a path needs inside an analytic sphere of homogeneous medium (else a room of radius 0).
  static SphereRoom sphere_room(const SceneGeometry::Ball& ball, const ChannelMedium& m, const SphereLookup* spheres);
  bool sphere_step(State& s, int c, const SphereRoom& room, PixelRng& rng, PathCounters& counters) const;
  // The largest sphere of `spheres` that fits at the path's point (its radius in r), or -1;
  // by_medium when the medium, not the free radius, limited it.
  int fitting_sphere(const State& s, const ChannelMedium& m, const SphereLookup& spheres, double& r, bool& by_medium) const;
  // The tightest bound the geometry gives at the path's point (the grid's eight cells).
  void look_closer(State& s) const;
  void stride(State& s, int c, const ShellSampler& sampler, double r, PixelRng& rng, PathCounters& counters) const;
  void ideal_stride(State& s, const ChannelMedium& m, double r, PixelRng& rng, PathCounters& counters) const;
  bool outside_step(State& s, int c, PixelRng& rng, PathCounters& counters) const;

  // An object's grid (if its medium has one) placed, with its stride rooms at `tolerance` (none
  // below 0: brute force asks for none), shared with a grid placed before.
  static PlacedGrid place_grid(const scene::MediumSpec& spec, const scene::ObjectSpec& o, double tolerance,
                               std::vector<PlacedGrid>& placed_before);

  const scene::RenderScene& scene_;
  const SceneGeometry& geometry_;
  std::vector<ChannelMedium> media_;            // [objects * 3]
  // [objects * 3]: after a collision the free radius is the one before less the flight (the
  // distance is 1-Lipschitz) while that is at least this: the largest sphere's radius, or the
  // depth below which shadow rays start to count (ln(0.5 / kShadowRoulette) / sigma_t).
  std::vector<double> refresh_below_;
  std::vector<std::shared_ptr<SphereLookup>> lookups_;  // [objects * 3], null where none
  std::vector<SphereRoom> rooms_;               // [objects * 3]
  std::vector<double> ior_;                     // per object
  std::shared_ptr<const EnvironmentMap> environment_;  // in place of the sky, or null
  Vec3 sun_;
  bool next_event_ = true, ideal_strides_ = false, exit_mis_ = true;
  double cos_sun_ = 1, sin_sun_ = 0, sun_pdf_ = 0;            // the disc's cosine and the uniform pdf over it
};

// Fresnel reflectance of unpolarised light at a smooth interface, going from index n_i to n_t
// at incidence cosine cos_i (> 0); 1 past the critical angle.
double fresnel_dielectric(double cos_i, double n_i, double n_t);

}  // namespace stf::render
