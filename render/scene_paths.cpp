#include "stf/render/scene_paths.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "stf/scene/scene_error.h"

namespace stf::render {

namespace {

// A shadow ray is cast with probability min(1, gain most / kShadowRoulette) and weighted up,
// where gain (f w / p: the vertex's density toward the light times the MIS weight over the
// light's density, at most 1/2) times the light's radiance times the transmittance bound `most`
// is the most the ray can bring: so no ray brings more than kShadowRoulette of its light's
// radiance, and rays that would bring little (deep in a dense medium, or where a forward phase
// function looks away from the sun) are mostly not cast.
// 0.005 measured best of 0.002, 0.005 and 0.02 on the lit torus for both methods
// (docs/studies/2026-12-stride-light.md).
constexpr double kShadowRoulette = 0.005;
// A path that has not ended after this many events (total internal reflection between two
// faces, say) is ended: its expected share is far below the noise.
constexpr int kMaxEvents = 1 << 24;

double power_heuristic(double a, double b) { return a * a / (a * a + b * b); }

double phase_density(const ChannelMedium& m, double mu) { return hg_pdf_mu(m.g(), mu) / (2 * kPi); }

// Inlined: it is a third of a collision's work, and a call costs the rest of the loop's registers.
[[gnu::always_inline]] inline Vec3 around(const Vec3& axis, double cos_theta, double sin_theta, double u) {
  double sp, cp;
  sincos_2pi(u, sp, cp);
  return Frame::around(axis).to_world({sin_theta * cp, sin_theta * sp, cos_theta});
}

}  // namespace

// A stride's exit as a scattering vertex: the exit direction density of its sphere's model at
// the exit point, in the frame of the stride's start direction.
struct ExitVertex {
  const ShellSampler* sampler = nullptr;  // null: the vertex is not a stride's exit
  Frame frame;
  Vec3 point;  // the exit point on the unit sphere, in `frame`
  double density(const Vec3& l) const { return sampler->exit_direction_pdf(point, frame.to_local(l)); }
};

struct ScenePaths::State {
  Vec3 x, w;
  double throughput = 1, radiance = 0;
  int inside = -1;           // the object whose medium the path is in, or -1
  bool after_nee = false;    // heading straight on from a vertex that cast a shadow ray
  // That vertex: a stride's exit, or a medium's collision (scatter_medium) or the ground (null),
  // with the cosine its density of w depends on; the density itself is needed only where the
  // path meets a light, far rarer than collisions.
  ExitVertex exit;
  const ChannelMedium* scatter_medium = nullptr;
  double scatter_cos = 0;
  double scatter_pdf() const {
    if (exit.sampler) return exit.density(w);
    return scatter_medium ? phase_density(*scatter_medium, scatter_cos) : scatter_cos / kPi;
  }
  double bound = -1;         // the free radius at x, when known
  bool tight = false;        // bound is the tightest the geometry gives at x (no closer look left)
  bool camera = true;        // no ray cast yet: the next is the camera's
};

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
  for (const scene::ObjectSpec& o : scene.objects) {
    ior_.push_back(o.ior);
    const scene::MediumSpec& spec = scene.media[std::size_t(o.medium)];
    for (std::size_t c = 0; c < 3; ++c) {
      const double ss = spec.sigma_s[c], sa = spec.sigma_a[c], g = spec.g[c];
      const ChannelMedium m = spec.grid ? ChannelMedium(ss, sa, g, {spec.grid, o.scale, o.translate, options.density_tolerance})
                                        : ChannelMedium(ss, sa, g);
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
      lookups_.push_back(std::move(lookup));
    }
  }
}

ScenePaths::~ScenePaths() = default;

const SphereLookup* ScenePaths::spheres(int object, int channel) const {
  return lookups_[std::size_t(object * 3 + channel)].get();
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

double ScenePaths::escape(const State& s, int c) const {
  double l = scene_.light.sky[std::size_t(c)];
  if (environment_) {
    l = environment_->radiance(s.w, c);
    if (s.after_nee && l > 0) l *= power_heuristic(s.scatter_pdf(), environment_->pdf(s.w));
  }
  if (dot(s.w, sun_) >= cos_sun_)
    l += scene_.light.sun[std::size_t(c)] * (s.after_nee ? power_heuristic(s.scatter_pdf(), sun_pdf_) : 1.0);
  return l;
}

Vec3 ScenePaths::toward_sun(PixelRng& rng) const {
  const double ct = 1 - rng.uniform() * (1 - cos_sun_);
  return around(sun_, ct, std::sqrt(std::max(0.0, 1 - ct * ct)), rng.uniform());
}

double ScenePaths::transmittance(Vec3 x, const Vec3& l, int c, RayKind kind, PixelRng& rng, PathCounters& counters) const {
  // Each crossing either leaves a medium (its chord attenuates) or enters one.
  double t = 1;
  for (int crossings = 0; crossings < 256; ++crossings) {
    const SurfaceHit h = geometry_.trace(x, l);
    counters.count_ray(kind);
    if (!h.found) return t;
    if (h.object == kGround || ior_[std::size_t(h.object)] != 1) return 0;  // opaque or specular
    if (dot(l, h.normal) > 0) t *= medium(h.object, c).transmittance(x, l, h.t, rng);
    x = geometry_.spawn(x + h.t * l, h.normal, l);
  }
  return 0;
}

template <typename Density, typename Start>
double ScenePaths::light_ray(const LightSample& light, const ShadowVertex& v, PixelRng& rng, PathCounters& counters,
                             const Density& density, const Start& start) const {
  const double f = density(light.l);
  if (!(f > 0) || !(light.radiance > 0)) return 0;
  const double gain = f / light.pdf * power_heuristic(light.pdf, f);
  const double cast = std::min(1.0, gain * v.most / kShadowRoulette);
  if (v.u >= cast) return 0;
  ++counters.shadow_rays;
  const double t = transmittance(start(light.l), light.l, v.channel, v.kind, rng, counters);
  return gain * t * light.radiance / cast;
}

template <typename Density, typename Start>
double ScenePaths::direct(const ShadowVertex& v, PixelRng& rng, PathCounters& counters,
                          const Density& density, const Start& start) const {
  const int c = v.channel;
  double sum = light_ray({toward_sun(rng), sun_pdf_, scene_.light.sun[std::size_t(c)]}, v, rng, counters, density, start);
  if (environment_) {
    LightSample map;
    map.l = environment_->sample(rng.uniform(), rng.uniform(), map.pdf);
    map.radiance = environment_->radiance(map.l, c);
    if (map.pdf > 0) sum += light_ray(map, v, rng, counters, density, start);
  }
  return sum;
}

bool ScenePaths::may_cast(double u, double most) { return u < 0.5 * most / kShadowRoulette; }

double ScenePaths::collision_gain_bound(const ChannelMedium& m, const Vec3& w) const {
  if (environment_) return 0.5;  // a map's rays may go anywhere
  // The phase density is monotone in the cosine: its largest over the disc is at the disc's
  // point nearest w (g >= 0; w itself where the disc holds it) or farthest from it (g < 0; -w
  // where the disc holds that).
  const double c = dot(w, sun_), s = std::sqrt(std::max(0.0, 1 - c * c));
  const double extreme = m.g() >= 0 ? (c >= cos_sun_ ? 1.0 : c * cos_sun_ + s * sin_sun_)
                                   : (-c >= cos_sun_ ? -1.0 : c * cos_sun_ - s * sin_sun_);
  return std::min(0.5, phase_density(m, extreme) / sun_pdf_);
}

void ScenePaths::nee_at_collision(State& s, int c, double bound, PixelRng& rng, PathCounters& counters) const {
  if (ior_[std::size_t(s.inside)] != 1) return;  // behind a dielectric no shadow ray passes
  const ChannelMedium& m = medium(s.inside, c);
  const double most = m.transmittance_bound(bound), u = rng.uniform();  // no direction leaves sooner
  if (!may_cast(u, most) || u >= collision_gain_bound(m, s.w) * most / kShadowRoulette) return;
  const Vec3 x = s.x, w = s.w;
  s.radiance += s.throughput * direct({c, kShadowCollision, most, u}, rng, counters,
                                      [&](const Vec3& l) { return phase_density(m, dot(w, l)); },
                                      [&](const Vec3&) { return x; });
}

void ScenePaths::nee_at_exit(State& s, int c, PixelRng& rng, PathCounters& counters) const {
  s.after_nee = exit_mis_, s.scatter_medium = nullptr;
  s.bound = geometry_.free_radius(s.x, s.inside), ++counters.distance_queries;  // the next step's too
  s.tight = geometry_.method() != FreeRadius::kGrid;
  const double most = medium(s.inside, c).transmittance_bound(s.bound), u = rng.uniform();
  if (!may_cast(u, most)) return;
  const Vec3 x = s.x;
  const ExitVertex& exit = s.exit;
  s.radiance += s.throughput * direct({c, kShadowExit, most, u}, rng, counters,
                                      [&](const Vec3& l) { return exit.density(l); }, [&](const Vec3&) { return x; });
}

bool ScenePaths::medium_step(State& s, int c, PixelRng& rng, PathCounters& counters) const {
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
    if (spheres) return true;  // the next step may stride
    if (!survives_roulette(s.throughput, rng)) return false;
  }
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
  if (next_event_) nee_at_collision(s, c, s.bound, rng, counters);
  const CosSin<double> cs = sample_hg(m.hg(), rng.uniform());
  s.exit.sampler = nullptr, s.scatter_medium = &m, s.scatter_cos = cs.cos_theta, s.after_nee = next_event_;
  s.w = around(s.w, cs.cos_theta, cs.sin_theta, rng.uniform());
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

bool ScenePaths::ground_bounce(State& s, int c, const SurfaceHit& h, PixelRng& rng, PathCounters& counters) const {
  const double albedo = scene_.ground.albedo[std::size_t(c)];
  if (albedo <= 0) return false;
  const Vec3 x = s.x;
  if (next_event_)  // nothing attenuates: every uniform passes may_cast
    s.radiance += s.throughput * albedo *
                  direct({c, kShadowGround, 1.0, rng.uniform()}, rng, counters, [](const Vec3& l) { return std::max(0.0, l.y) / kPi; },
                         [&](const Vec3& l) { return geometry_.spawn(x, h.normal, l); });
  const double u = rng.uniform(), cos_o = std::sqrt(1 - u);  // cosine-weighted
  s.w = around(h.normal, cos_o, std::sqrt(u), rng.uniform());
  s.exit.sampler = nullptr, s.scatter_medium = nullptr, s.scatter_cos = cos_o, s.after_nee = next_event_;
  s.throughput *= albedo;
  s.x = geometry_.spawn(s.x, h.normal, s.w);
  return true;
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
