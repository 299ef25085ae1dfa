// The inside of ScenePaths (stf/render/scene_paths.h) shared by its two sources: a path's
// state, a stride's exit as a scattering vertex, and the small functions both use
// (scene_paths.cpp walks paths, next_event.cpp casts their shadow rays).
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>

#include <stf/sampler.h>

#include "stf/render/medium.h"

namespace stf::render {

// A shadow ray is cast with probability min(1, gain most / kShadowRoulette) and weighted up,
// where gain (f w / p: the vertex's density toward the light times the MIS weight over the
// light's density, at most 1/2) times the light's radiance times the transmittance bound `most`
// is the most the ray can bring: so no ray brings more than kShadowRoulette of its light's
// radiance, and rays that would bring little (deep in a dense medium, or where a forward phase
// function looks away from the sun) are mostly not cast.
// 0.005 measured best of 0.002, 0.005 and 0.02 on the lit torus for both methods
// (docs/studies/2026-12-stride-light.md).
inline constexpr double kShadowRoulette = 0.005;
inline double power_heuristic(double a, double b) { return a * a / (a * a + b * b); }
// One uniform u decides a vertex's shadow rays: cast toward a light of gain g with probability
// min(1, g most / kShadowRoulette), u below it. Before any light is drawn, u is held against the
// most any gain allows (1/2): deep in a medium most vertices stop there.
inline bool may_cast(double u, double most) { return u < 0.5 * most / kShadowRoulette; }
// may_cast(u, exp(-depth)) where a power of two below exp(depth), 2^k with k = floor(depth
// log2(e)) less a margin for rounding, settles it without the exponential: false only where
// may_cast is false. Deep in a dense medium nearly every collision stops here (brute force spent
// a third of its time on those exponentials).
inline bool may_pass(double u, double depth) {
  if (depth < 4.6) return true;  // below ln(0.5 / kShadowRoulette) = 4.605 every u passes: the shallow, at once
  if (!(depth < 700)) return false;  // exp(-depth) is below 1e-304, or depth is not a number: none passes
  const int k = int(depth * 1.4426950408889634 - 1e-6);
  return u * std::bit_cast<double>(std::uint64_t(k + 1023) << 52) < 0.5 / kShadowRoulette;
}

inline double phase_density(const ChannelMedium& m, double mu) { return hg_pdf_mu(m.g(), mu) / (2 * kPi); }

// Inlined: it is a third of a collision's work, and a call costs the rest of the loop's registers.
[[gnu::always_inline]] inline Vec3 around(const Vec3& axis, double cos_theta, double sin_theta, double u) {
  double sp, cp;
  sincos_2pi(u, sp, cp);
  return Frame::around(axis).to_world({sin_theta * cp, sin_theta * sp, cos_theta});
}


// A stride's exit as a scattering vertex: the exit direction density of its sphere's model at
// the exit point, in the frame of the stride's start direction.
struct ExitVertex {
  const ShellSampler* sampler = nullptr;  // null: the vertex is not a stride's exit
  Frame frame;
  Vec3 point;  // the exit point on the unit sphere, in `frame`
  double density(const Vec3& l) const { return sampler->exit_direction_pdf(point, frame.to_local(l)); }
};

struct PathState {
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

}  // namespace stf::render
