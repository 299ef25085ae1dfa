// von Mises-Fisher lobes on the unit sphere: density and mixtures.
#pragma once

#include <algorithm>
#include <cmath>

#include "stf/math.h"
#include "stf/vec3.h"

namespace stf {

// Largest concentration a model may hold (a lobe about 3e-5 rad wide); loaders refuse more.
inline constexpr double kMaxKappa = 1e9;

struct VmfLobe {
  double weight = 1;  // mixture weight; the weights of a mixture sum to 1
  double kappa = 0;   // concentration >= 0 (0: uniform)
  Vec3 mean{0, 0, 1};
};

// vMF density per steradian at cos(angle to the mean) = c, in the stable form
//   kappa / (2 pi (1 - exp(-2 kappa))) * exp(kappa (c - 1)),
// which neither overflows at kappa ~ 1e7 (unlike sinh) nor loses precision as kappa -> 0
// (expm1 keeps kappa / (1 - e^{-2 kappa}) -> 1/2, the uniform 1 / (4 pi)). Templated so the
// fitter can differentiate it (T = ceres::Jet).
template <typename T>
inline T vmf_pdf(const T& kappa, const T& c) {
  using std::exp;
  using std::expm1;
  T norm = kappa < T(1e-12) ? T(0.5) + T(0.5) * kappa : kappa / -expm1(T(-2) * kappa);
  return norm / T(2 * kPi) * exp(kappa * (c - T(1)));
}

// cos(angle to the mean) of a vMF sample from u in [0, 1), by the stable inversion
// 1 + log(u + (1 - u) e^{-2 kappa}) / kappa (W. Jakob 2012), written with log1p and expm1 so
// that kappa -> 0 tends to the uniform 2u - 1 and kappa ~ 1e7 does not underflow to -inf.
inline double sample_vmf_cos(double kappa, double u) {
  if (kappa < 1e-300) return 2 * u - 1;
  double c = 1 + std::log1p((1 - u) * std::expm1(-2 * kappa)) / kappa;
  return c < -1 ? -1 : (c > 1 ? 1 : c);
}

// A lobe made for drawing: its frame and the constants of its quantile, computed once.
struct VmfFrame {
  Frame frame;  // z is the mean
  double kappa = 0, expm1_2k = 0, inv_kappa = 0;
  VmfFrame() = default;
  explicit VmfFrame(const VmfLobe& l)
      : frame(Frame::around(l.mean)), kappa(l.kappa), expm1_2k(std::expm1(-2 * l.kappa)),
        inv_kappa(l.kappa > 0 ? 1 / l.kappa : 0) {}
  const Vec3& mean() const { return frame.z; }
  // The direction at quantile u of cos(theta) and azimuth 2 pi v: sample_vmf_cos's stable
  // inversion with expm1(-2 kappa) cached, and log for kappa >= 1, where 1 + x loses nothing
  // that matters (an absolute 1e-16 / kappa in c) and log is several times cheaper than log1p.
  Vec3 direction(double u, double v) const {
    const double t = (1 - u) * expm1_2k;
    double c = kappa < 1e-300 ? 2 * u - 1 : 1 + (kappa >= 1 ? std::log(1 + t) : std::log1p(t)) * inv_kappa;
    c = std::clamp(c, -1.0, 1.0);
    double s = std::sqrt(std::max(0.0, 1 - c * c)), sp, cp;
    sincos_2pi(v, sp, cp);
    return frame.to_world({s * cp, s * sp, c});  // unit to rounding
  }
};

// A lifted lobe's direction (StfModel::lifted): the half-vector of the exit normal n and a lobe
// direction v (v = -n, of probability 0, gives n).
inline Vec3 lift_direction(const Vec3& v, const Vec3& n) {
  const Vec3 h{v.x + n.x, v.y + n.y, v.z + n.z};
  const double square = h.x * h.x + h.y * h.y + h.z * h.z;
  if (!(square > 1e-300)) return n;
  const double inv = 1 / std::sqrt(square);
  return {h.x * inv, h.y * inv, h.z * inv};
}

// A lifted density at w about the exit normal n, from its lobes' density `pdf` over the whole
// sphere: 4 (w . n) pdf(v) at v = 2 (w . n) w - n (n mirrored about w, the direction whose
// half-vector with n is w; 4 (w . n) the Jacobian), 0 below n's tangent plane.
template <typename Pdf>
double lifted_pdf(const Vec3& w, const Vec3& n, Pdf&& pdf) {
  const double up = dot(w, n);
  return up > 0 ? 4 * up * pdf(2 * up * w - n) : 0.0;
}

// A vMF direction from (u0, u1) in [0, 1)^2.
inline Vec3 sample_vmf(const VmfLobe& lobe, double u0, double u1) {
  double c = sample_vmf_cos(lobe.kappa, u0), s = std::sqrt(std::max(0.0, 1 - c * c));
  double phi = 2 * kPi * u1;
  return normalize(Frame::around(lobe.mean).to_world({s * std::cos(phi), s * std::sin(phi), c}));
}

}  // namespace stf
