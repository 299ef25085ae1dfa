// Next-event estimation of the scene's paths: shadow rays from collisions, stride exits and the
// ground toward the sun and the environment map, weighted by the power heuristic against the
// vertex's own density and cast by Russian roulette against the most they can bring.
#include <algorithm>
#include <cmath>

#include "path_state.h"
#include "stf/render/scene_paths.h"

namespace stf::render {

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

void ScenePaths::nee_at_collision(State& s, int c, const ShadowOdds& odds, PixelRng& rng, PathCounters& counters) const {
  const ChannelMedium& m = medium(s.inside, c);
  const double most = std::exp(-odds.depth), u = odds.u;  // no direction leaves sooner
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
  const ChannelMedium& m = medium(s.inside, c);
  const double u = rng.uniform();
  const double depth = m.least_optical_depth(s.x, s.bound);
  if (!may_pass(u, depth)) return;
  const double most = std::exp(-depth);
  if (!may_cast(u, most)) return;
  const Vec3 x = s.x;
  const ExitVertex& exit = s.exit;
  s.radiance += s.throughput * direct({c, kShadowExit, most, u}, rng, counters,
                                      [&](const Vec3& l) { return exit.density(l); }, [&](const Vec3&) { return x; });
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

}  // namespace stf::render
