#include "stf/render/scene_paths.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "path_state.h"
#include "stf/scene/scene_error.h"

namespace stf::render {

namespace {

// A path that has not ended after this many events (total internal reflection between two
// faces, say) is ended: its expected share is far below the noise.
constexpr int kMaxEvents = 1 << 24;

}  // namespace

ScenePaths::SphereRoom ScenePaths::sphere_room(const SceneGeometry::Ball& ball, const ChannelMedium& m, const SphereLookup* spheres) {
  ScenePaths::SphereRoom room;
  if (ball.radius <= 0 || !m.homogeneous()) return room;
  room.centre = ball.centre, room.radius = ball.radius, room.radius2 = ball.radius * ball.radius;
  for (int k = 0; spheres && k < spheres->size(); ++k) {
    const double r = spheres->tau(k) / m.sigma_t(), room_left = ball.radius - r;
    room.stride_radius.push_back(r);
    room.limit2.push_back(room_left >= 0 ? room_left * room_left : -1.0);
  }
  return room;
}

double fresnel_dielectric(double cos_i, double n_i, double n_t) {
  const double sin_t2 = (n_i / n_t) * (n_i / n_t) * std::max(0.0, 1 - cos_i * cos_i);
  if (sin_t2 >= 1) return 1;
  const double cos_t = std::sqrt(1 - sin_t2);
  const double rs = (n_i * cos_i - n_t * cos_t) / (n_i * cos_i + n_t * cos_t);
  const double rp = (n_t * cos_i - n_i * cos_t) / (n_t * cos_i + n_i * cos_t);
  return 0.5 * (rs * rs + rp * rp);
}

std::shared_ptr<const EnvironmentMap> read_environment(const scene::RenderScene& scene) {
  if (scene.light.environment.empty()) return nullptr;
  try {
    return std::make_shared<const EnvironmentMap>(EnvironmentMap::from_file(scene.light.environment, scene.light.environment_scale));
  } catch (const std::exception& e) {
    throw scene::SceneError(scene.path + ": light.environment: " + e.what());
  }
}

ScenePaths::ScenePaths(const scene::RenderScene& scene, const SceneGeometry& geometry, const std::vector<PackEntry>* pack,
                       PathOptions options)
    : scene_(scene), geometry_(geometry), environment_(read_environment(scene)), sun_(scene.light.sun_direction),
      next_event_(options.next_event), ideal_strides_(options.ideal_strides), exit_mis_(options.exit_mis) {
  cos_sun_ = std::cos(scene.light.sun_angle * kPi / 180), sin_sun_ = std::sin(scene.light.sun_angle * kPi / 180);
  sun_pdf_ = 1 / (2 * kPi * (1 - cos_sun_));
  // Channels (of any object) of one albedo and g stride through the same spheres: one lookup
  // for them all, whose samplers are built once.
  std::vector<std::pair<std::pair<double, double>, std::shared_ptr<SphereLookup>>> built;
  std::vector<PlacedGrid> grids;  // placed so far: objects of one grid share its stride rooms
  for (const scene::ObjectSpec& o : scene.objects) {
    ior_.push_back(o.ior);
    const scene::MediumSpec& spec = scene.media[std::size_t(o.medium)];
    const PlacedGrid placed = place_grid(spec, o, pack ? options.density_tolerance : -1.0, grids);
    for (std::size_t c = 0; c < 3; ++c) {
      const double ss = spec.sigma_s[c], sa = spec.sigma_a[c], g = spec.g[c];
      const ChannelMedium m = spec.grid ? ChannelMedium(ss, sa, g, placed) : ChannelMedium(ss, sa, g);
      std::shared_ptr<SphereLookup> lookup;
      const auto same = std::find_if(built.begin(), built.end(), [&](const auto& b) { return b.first == std::pair(m.albedo(), g); });
      if (same != built.end()) {
        lookup = same->second;
      } else if (pack) {
        lookup = std::make_shared<SphereLookup>(*pack, m.albedo(), g);
        if (lookup->size() == 0) lookup.reset();
        built.push_back({{m.albedo(), g}, lookup});
      }
      const double inv_sigma_t = 1 / m.sigma_t();
      double refresh = std::log(0.5 / kShadowRoulette) * inv_sigma_t;
      // Where the density limits strides more than the boundary does (a grid), a fresher bound
      // would rarely buy a stride: the carried one serves.
      if (lookup && m.homogeneous()) refresh = std::max(refresh, lookup->tau(lookup->size() - 1) * inv_sigma_t);
      media_.push_back(m);
      refresh_below_.push_back(refresh);
      rooms_.push_back(sphere_room(geometry.sphere(int(ior_.size()) - 1), m, lookup.get()));
      rooms_.back().alone = scene.objects.size() == 1 && !scene.ground.present && o.ior == 1;
      lookups_.push_back(std::move(lookup));
    }
  }
}

ScenePaths::~ScenePaths() = default;

PlacedGrid ScenePaths::place_grid(const scene::MediumSpec& spec, const scene::ObjectSpec& o, double tolerance,
                                  std::vector<PlacedGrid>& placed_before) {
  PlacedGrid placed{spec.grid, o.scale, o.translate, tolerance, nullptr};
  if (!spec.grid || tolerance < 0) return placed;
  for (const PlacedGrid& p : placed_before)
    if (p.grid == spec.grid) placed.rooms = p.rooms;
  if (!placed.rooms) placed.rooms = std::make_shared<const media::StrideRooms>(media::stride_rooms(*spec.grid, tolerance));
  placed_before.push_back(placed);
  return placed;
}

double ScenePaths::radiance(const Vec3& origin, const Vec3& direction, int c, PixelRng& rng, PathCounters& counters) const {
  State s;
  s.x = origin, s.w = direction;
  for (int events = 0; events < kMaxEvents; ++events) {
    const bool goes_on = s.inside >= 0 ? medium_step(s, c, rng, counters) : outside_step(s, c, rng, counters);
    if (!goes_on || !survives_roulette(s.throughput, rng)) break;
  }
  return s.radiance;
}

bool ScenePaths::medium_step(State& s, int c, PixelRng& rng, PathCounters& counters) const {
  const SphereRoom& room = rooms_[std::size_t(s.inside * 3 + c)];
  if (room.radius > 0) return sphere_step(s, c, room, rng, counters);
  const ChannelMedium& m = medium(s.inside, c);
  if (s.bound < 0) {
    s.bound = geometry_.free_radius(s.x, s.inside), ++counters.distance_queries;
    s.tight = geometry_.method() != FreeRadius::kGrid;  // an exact query leaves nothing closer
  }
  const SphereLookup* spheres = this->spheres(s.inside, c);
  if (spheres) {
    double r;
    bool by_medium = false;
    int k = fitting_sphere(s, m, *spheres, r, by_medium);
    if (k < 0 && !s.tight && !by_medium) {  // the one-cell bound fits none: look closer
      look_closer(s);
      ++counters.distance_queries;
      k = fitting_sphere(s, m, *spheres, r, by_medium);
    }
    if (k >= 0) {
      if (ideal_strides_) ideal_stride(s, m, r, rng, counters);
      else stride(s, c, spheres->sampler(k), r, rng, counters);
      return true;
    }
  }
  // Collision after collision until the path reaches the boundary, may stride, or ends: one call
  // for the many collisions deep in a medium, the roulette the same draws as the outer loop's.
  for (;;) {
    const double t = m.flight(s.x, s.w, rng, counters);
    if (t >= s.bound && !s.tight) look_closer(s), ++counters.distance_queries;  // before a ray
    if (t >= s.bound) {  // the flight may reach the boundary
      const SurfaceHit h = geometry_.trace(s.x, s.w, t);
      counters.count_ray(kFlightRay);
      if (h.found) {
        s.x += h.t * s.w, s.bound = -1;
        cross(s, h, rng);
        return true;
      }
      if (!std::isfinite(t)) return false;  // a grid's flight past a boundary no ray found: lost in rounding
    }
    collide(s, c, m, t, rng, counters);
    // The next step may stride, unless the closest look has just left no room for the smallest
    // sphere (the boundary shell): then the next collision follows here, with the outer loop's draws.
    if (spheres && !(m.homogeneous() && s.tight && m.sigma_t() * s.bound < spheres->tau(0))) return true;
    if (!survives_roulette(s.throughput, rng)) return false;
  }
}

// Inlined into both collision loops: a call costs them their registers.
[[gnu::always_inline]] inline Vec3 ScenePaths::scatter(State& s, const ChannelMedium& m, const Vec3& w, PixelRng& rng) const {
  const CosSin<double> cs = sample_hg(m.hg(), rng.uniform());
  s.exit.sampler = nullptr, s.scatter_medium = &m, s.scatter_cos = cs.cos_theta, s.after_nee = next_event_;
  return around(w, cs.cos_theta, cs.sin_theta, rng.uniform());
}

// Inlined into both collision loops: deep in a medium it is all a collision's lighting costs.
[[gnu::always_inline]] inline bool ScenePaths::may_light(const State& s, const Vec3& x, const ChannelMedium& m, double bound,
                                                         ShadowOdds& odds, PixelRng& rng) const {
  if (!next_event_ || ior_[std::size_t(s.inside)] != 1) return false;  // behind a dielectric no shadow ray passes
  odds.u = rng.uniform(), odds.depth = m.least_optical_depth(x, bound);
  return may_pass(odds.u, odds.depth);
}

void ScenePaths::collide(State& s, int c, const ChannelMedium& m, double t, PixelRng& rng, PathCounters& counters) const {
  s.x += t * s.w;
  ++counters.collisions;
  s.throughput *= m.albedo();
  // Carried, the bound loses the flight; refreshed, it is the closest look at once: in the
  // boundary shell the next step would otherwise ask again, for a sphere or before a ray.
  s.tight = false;
  if (s.bound - t >= refresh_below_[std::size_t(s.inside * 3 + c)]) s.bound -= t;
  else s.bound = 0, look_closer(s), ++counters.distance_queries;
  ShadowOdds odds;
  if (may_light(s, s.x, m, s.bound, odds, rng)) nee_at_collision(s, c, odds, rng, counters);
  s.w = scatter(s, m, s.w, rng);
}

bool ScenePaths::sphere_step(State& s, int c, const SphereRoom& room, PixelRng& rng, PathCounters& counters) const {
  const ChannelMedium& m = medium(s.inside, c);
  const SphereLookup* spheres = this->spheres(s.inside, c);
  // The point from the centre and the direction stay in registers; the state takes them where a
  // call reads it (a stride, shadow rays, the way out).
  Vec3 o = s.x - room.centre, w = s.w;
  for (;;) {
    const int k = spheres ? room.fitting(dot(o, o)) : -1;
    if (k >= 0) {
      s.x = room.centre + o, s.w = w;
      if (ideal_strides_) ideal_stride(s, m, room.stride_radius[std::size_t(k)], rng, counters);
      else stride(s, c, spheres->sampler(k), room.stride_radius[std::size_t(k)], rng, counters);
      if (!survives_roulette(s.throughput, rng)) return false;
      o = s.x - room.centre, w = s.w;
      continue;
    }
    const double t = m.homogeneous_flight(rng);
    const Vec3 y = o + t * w;
    if (dot(y, y) > room.radius2) {  // the flight leaves: where, exactly
      s.x = room.centre + o, s.w = w;
      counters.count_ray(kFlightRay);
      if (room.alone) {
        s.radiance += s.throughput * escape(s, c);
        return false;
      }
      const SurfaceHit h = geometry_.leave_sphere(s.x, w, s.inside);
      if (h.found) {
        s.x += h.t * w, s.bound = -1;
        cross(s, h, rng);
        return true;
      }
    }
    o = y;
    ++counters.collisions;
    s.throughput *= m.albedo();
    if (next_event_) {
      const double bound = room.radius - length(o);
      const Vec3 x = room.centre + o;
      ShadowOdds odds;
      if (may_light(s, x, m, bound, odds, rng)) s.x = x, s.w = w, s.bound = bound, nee_at_collision(s, c, odds, rng, counters);
    }
    w = scatter(s, m, w, rng);
    if (!survives_roulette(s.throughput, rng)) return false;
  }
}

int ScenePaths::fitting_sphere(const State& s, const ChannelMedium& m, const SphereLookup& spheres, double& r,
                               bool& by_medium) const {
  const StrideBall ball = m.stride_ball(s.x, s.bound, spheres.tau(0), spheres.tau(spheres.size() - 1));
  by_medium = ball.by_medium;
  return ball.radius > 0 ? spheres.find(ball.sigma_t, ball.radius, r) : -1;
}

void ScenePaths::look_closer(State& s) const {
  s.bound = std::max(s.bound, geometry_.tight_free_radius(s.x, s.inside));
  s.tight = true;
}

void ScenePaths::stride(State& s, int c, const ShellSampler& sampler, double r, PixelRng& rng,
                        PathCounters& counters) const {
  const StrideForm& form = sampler.stride_form();
  const Vec3 centre = s.x, start = s.w;
  const Stride e = form.jump(s.x, s.w, r, [&rng] { return rng.uniform(); });
  s.x = e.point, s.w = e.direction, s.bound = -1;
  s.throughput *= form.escape_probability();
  ++counters.strides;
  if (e.component == kUncollided) return;  // straight on: the vertex before keeps its weight
  if (e.component != kSmooth) {  // once scattered: its directions lie on a curve, no density
    s.after_nee = false, ++counters.once_scattered_exits;
    return;
  }
  if (!next_event_ || ior_[std::size_t(s.inside)] != 1) {  // behind a dielectric no shadow ray passes
    s.after_nee = false;
    return;
  }
  const Frame f = Frame::around(start);
  s.exit = {&sampler, f, f.to_local((s.x - centre) / r)};
  nee_at_exit(s, c, rng, counters);
}

void ScenePaths::ideal_stride(State& s, const ChannelMedium& m, double r, PixelRng& rng, PathCounters& counters) const {
  const Vec3 centre = s.x;
  for (;;) {
    const double t = m.flight(s.x, s.w, rng, counters);  // in a grid, its density as it is: exact
    const Vec3 o = s.x - centre;
    const double b = dot(o, s.w), out = -b + std::sqrt(std::max(0.0, b * b - (dot(o, o) - r * r)));
    if (t >= out) {  // leaves the sphere: its exit, on the sphere
      s.x += out * s.w;
      break;
    }
    s.x += t * s.w;
    ++counters.ideal_collisions;
    s.throughput *= m.albedo(), s.after_nee = false;
    const CosSin<double> cs = sample_hg(m.hg(), rng.uniform());
    s.w = around(s.w, cs.cos_theta, cs.sin_theta, rng.uniform());
  }
  s.bound = -1;
  ++counters.strides;
}

void ScenePaths::cross(State& s, const SurfaceHit& h, PixelRng& rng) const {
  const bool leaving = dot(s.w, h.normal) > 0;
  const double eta = ior_[std::size_t(h.object)];
  if (eta != 1) {
    // The normal on the side the path comes from, and Fresnel's choice of the two ways on.
    const Vec3 n = leaving ? -h.normal : h.normal;
    const double cos_i = -dot(s.w, n), n_i = leaving ? eta : 1.0, n_t = leaving ? 1.0 : eta;
    s.after_nee = false;  // a specular event: no shadow ray could have reached on along this path
    if (rng.uniform() < fresnel_dielectric(cos_i, n_i, n_t)) {
      s.w = s.w + 2 * cos_i * n;
      s.x = geometry_.spawn(s.x, h.normal, s.w);
      return;
    }
    const double r = n_i / n_t, cos_t = std::sqrt(std::max(0.0, 1 - r * r * (1 - cos_i * cos_i)));
    s.w = normalize(r * s.w + (r * cos_i - cos_t) * n);
  }
  s.inside = leaving ? -1 : h.object;
  s.x = geometry_.spawn(s.x, h.normal, s.w);
}

bool ScenePaths::outside_step(State& s, int c, PixelRng& rng, PathCounters& counters) const {
  const SurfaceHit h = geometry_.trace(s.x, s.w);
  counters.count_ray(s.camera ? kCameraRay : kOutsideRay);
  s.camera = false;
  if (!h.found) {
    s.radiance += s.throughput * escape(s, c);
    return false;
  }
  s.x += h.t * s.w, s.bound = -1;
  if (h.object == kGround) return ground_bounce(s, c, h, rng, counters);
  cross(s, h, rng);
  return true;
}

}  // namespace stf::render
