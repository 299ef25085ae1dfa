// The stride form of a fitted model: one jump of a path through a precomputed sphere, for a
// renderer's inner loop (docs/render.md, "The stride form").
//
// It draws what ShellSampler::sample draws (exactly, but for exit angles within 1e-10 rad), with
// everything that depends only on the model resolved when the form is built:
//  - one alias table picks the part (once scattered, uncollided) or the smooth part's alpha
//    bin, its remainder placing the exit point in the bin, through the bin's polynomial of
//    the exit angle where it has one (kAngleError);
//  - each bin keeps its cosine edges (also as 1 - cos and 1 + cos, so sin(alpha) keeps its
//    digits near the poles), its tilt and the sine and cosine of its middle, so the turn with
//    the exit angle needs no libm trigonometry: the angle from the middle is a short series in
//    its half-angle tangent, its sine and cosine sincos_2pi's polynomials;
//  - each lobe keeps its frame and its quantile's constants;
//  - the exit point and direction reach the world through one frame, turned by the azimuth.
// A draw takes its uniforms from the renderer's own generator, as many as it needs (6 or 7, and
// 3 more for each retry), so no retry needs a stream of its own.
//
// Hemispherical lobes (a vMF lobe times its bin's outward factor) have no closed-form inverse:
// a lobe draw is kept with the probability of its outward factor (at most 1), and redrawn
// otherwise. That is exact; the tries per kept draw are 1 / (the lobe's mean outward factor).
// Lifted lobes (StfModel::lifted) have the same fall-off at grazing and draw in one go: a lobe
// direction, plus the exit normal, normalised (docs/render.md, "Lifted lobes").
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "stf/alias.h"
#include "stf/hemisphere.h"
#include "stf/math.h"
#include "stf/model.h"
#include "stf/draw_tables.h"
#include "stf/tilt.h"
#include "stf/vec3.h"

namespace stf {

struct Stride {
  Vec3 point;      // exit point (world, or the unit sphere's in the local frame)
  Vec3 direction;  // exit direction
  int component = kSmooth;
};

// atan(t) for the half-angle tangents of angles within a bin of its middle: the Taylor series,
// to t^9 for |t| <= 0.02 (bins of 7 degrees or less; below 1e-19 off) and to t^19 for
// |t| <= 0.15 (bins up to 34 degrees; below 3e-19 off); libm beyond.
inline double atan_near_zero(double t) {
  const double t2 = t * t;
  if (std::abs(t) <= 0.02) return t + t * t2 * (-1.0 / 3 + t2 * (1.0 / 5 + t2 * (-1.0 / 7 + t2 * (1.0 / 9))));
  if (std::abs(t) > 0.15) return std::atan(t);
  double p = -1.0 / 19;
  for (int k = 17; k >= 3; k -= 2) p = p * t2 + (k % 4 == 1 ? 1.0 : -1.0) / k;
  return t + t * t2 * p;
}

// sin and cos of any angle: the Taylor series to a^13 / a^14 for |a| <= 0.3 (below 1e-20 off;
// turns within a bin are small), else sincos_2pi's polynomials. The series are summed in pairs
// of terms (Estrin's scheme: three short chains of multiply-adds rather than one of six).
inline void sincos_angle(double angle, double& s, double& c) {
  if (std::abs(angle) <= 0.3) {
    const double y = angle * angle, y2 = y * y, y4 = y2 * y2;
    const double sp = (-1.0 / 6 + y * (1.0 / 120)) + (-1.0 / 5040 + y * (1.0 / 362880)) * y2 +
                      (-1.0 / 39916800 + y * (1.0 / 6227020800)) * y4;
    const double cp = (-0.5 + y * (1.0 / 24)) + (-1.0 / 720 + y * (1.0 / 40320)) * y2 +
                      ((-1.0 / 3628800 + y * (1.0 / 479001600)) + y2 * (-1.0 / 87178291200)) * y4;
    s = angle + angle * y * sp, c = 1 + y * cp;
    return;
  }
  double turns = angle * (0.5 / kPi);
  turns -= std::floor(turns);
  sincos_2pi(turns, s, c);
}

class StrideForm {
 public:
  // A bin's exit angle is drawn through a polynomial of this degree where it is within
  // kAngleError radians of the exact quantile and its derivative within kAngleSlopeError
  // (relative: the exit points' density, so the TV distance to the model's, is off by at most
  // half that).
  static constexpr int kAngleDegree = 9;
  static constexpr double kAngleError = 1e-10, kAngleSlopeError = 1e-7;
  // A bin's polynomial at x, by Estrin's scheme (the draw's exit angle waited on nine dependent
  // multiply-adds of Horner's; bench/stride_cost).
  static double angle_polynomial(const double (&a)[kAngleDegree + 1], double x) {
    static_assert(kAngleDegree == 9, "the scheme below sums ten coefficients");
    const double x2 = x * x, x4 = x2 * x2, x8 = x4 * x4;
    const double low = (a[0] + a[1] * x) + (a[2] + a[3] * x) * x2, high = (a[4] + a[5] * x) + (a[6] + a[7] * x) * x2;
    return low + high * x4 + (a[8] + a[9] * x) * x8;
  }

  // The model must be valid (as read_pack or fit/ produce it). `tables`, when given, must be the
  // draw tables of this model (a ShellSampler's tables()); else they are built here.
  explicit StrideForm(const StfModel& model, std::shared_ptr<const DrawTables> tables = nullptr);
  StrideForm() = default;  // draws nothing until assigned

  // The exit of a path at `position` heading `direction` (unit) through the sphere of
  // `radius` around it; `uniform()` returns independent uniforms in [0, 1).
  template <typename Uniform>
  Stride jump(const Vec3& position, const Vec3& direction, double radius, Uniform&& uniform) const {
    Stride s = draw(Frame::around(direction), uniform);
    s.point = position + radius * s.point;
    return s;
  }
  // The same draw in the local frame (start at the centre of the unit sphere heading +z).
  template <typename Uniform>
  Stride local(Uniform&& uniform) const {
    return draw(Frame(), uniform);
  }

  double escape_probability() const { return escape_probability_; }
  // The exit point (sin alpha, 0, cos alpha) that bin b's smooth part draws at remainder r of
  // the alias draw (through the polynomial where the bin has one).
  Vec3 exit_point(int bin, double r) const {
    const ExitAngle a = exit_angle(bin_[std::size_t(bin)], r);
    return {a.sin_alpha, 0, a.cos_alpha};
  }
  // How many alpha bins draw their exit angle through the polynomial.
  int polynomial_bins() const {
    return int(std::count_if(bin_.begin(), bin_.end(), [](const Bin& b) { return !b.exact; }));
  }

 private:
  struct Bin {
    double c0, dc;       // cos(alpha) at the lower alpha edge, and its change across the bin
    double om0, dom;     // the same for 1 - cos(alpha)
    double op0, dop;     // and for 1 + cos(alpha)
    double tilt, expm1_tilt, inv_tilt;
    double middle, cos_middle, sin_middle;
    double turn;         // the bin's turn rate (StfModel::alpha_turn)
    int blend;           // blend width
    double inv_dc;
    // The exit angle less the middle, alpha(r) - middle, as a polynomial in x = 2 r - 1 of the
    // alias remainder r (coefficients of x^0 .. x^kAngleDegree), where it meets
    // kAngleError; else `exact` and the exit angle comes from the tilt's quantile.
    bool exact = true;
    double angle[kAngleDegree + 1] = {};
  };
  using Lobe = VmfFrame;
  // An exit point of bin b at the remainder r of the alias draw: cos and sin of alpha, the
  // area fraction u and the angle from the bin's middle.
  struct ExitAngle {
    double cos_alpha, sin_alpha, u, from_middle;
  };
  ExitAngle exit_angle(const Bin& bin, double r) const;
  // Fits bin's exit-angle polynomial (alpha edges a0, a1); false where it misses the errors.
  static bool fit_angle(Bin& bin, double a0, double a1);
  // The blended bin whose density draws the direction at area fraction u of bin b.
  int blend_pick(int b, double u, double v) const;
  Vec3 sh_direction(int bin, double u, double v) const;
  // Bin `bin`'s direction; lifted lobes about `normal` (the exit normal turned back by the bin's
  // turn).
  template <typename Uniform>
  Vec3 direction(int bin, const Vec3& normal, Uniform& uniform) const;
  Stride once_scattered(double r, double u1, double u2, double u3) const;
  // A draw on the unit sphere about the origin, in frame f (f.z the start direction): the
  // azimuth turns f once, and the exit point and direction are read off the turned frame.
  template <typename Uniform>
  Stride draw(const Frame& f, Uniform& uniform) const;

  int bins_ = 0, lobes_per_bin_ = 0;
  bool sh_ = false, turns_ = false, lifted_ = false;
  double escape_probability_ = 0;
  AliasTable outcomes_;  // [bins] smooth bins, then the uncollided delta, then once scattered
  std::vector<Bin> bin_;
  std::vector<Lobe> lobe_;       // vmf: [bins * lobes]
  int sh_nz_ = 0;
  std::shared_ptr<const DrawTables> tables_;  // lobe sums, SH cells, outward factors, once scattered
};

template <typename Uniform>
Vec3 StrideForm::direction(int bin, const Vec3& normal, Uniform& uniform) const {
  if (sh_) {
    const double u = uniform();
    return sh_direction(bin, u, uniform());
  }
  const double* sums = &tables_->lobe_cdf[std::size_t(bin) * std::size_t(lobes_per_bin_)];
  const Lobe& l = bin_slice(lobe_, bin, lobes_per_bin_)[std::size_t(pick_lobe(sums, lobes_per_bin_, uniform()))];
  if (tables_->outward.empty()) {
    const double u = uniform();
    const Vec3 v = l.direction(u, uniform());
    return lifted_ ? lift_direction(v, normal) : v;
  }
  const OutwardBin& factor = tables_->outward[std::size_t(bin)];
  for (;;) {
    const double u = uniform(), v = uniform();
    const Vec3 w = l.direction(u, v);
    if (uniform() < factor(w)) return w;
  }
}

template <typename Uniform>
Stride StrideForm::draw(const Frame& f, Uniform& uniform) const {
  double r;
  const int outcome = outcomes_.sample(uniform(), r);
  if (outcome == bins_) return {f.z, f.z, kUncollided};  // straight through: nothing to draw
  if (outcome > bins_) {
    const double u1 = uniform(), u2 = uniform();
    const Stride s = once_scattered(r, u1, u2, uniform());
    return {f.to_world(s.point), f.to_world(s.direction), s.component};
  }
  const Bin& bin = bin_[std::size_t(outcome)];
  const ExitAngle a = exit_angle(bin, r);
  double sb, cb;
  sincos_2pi(uniform(), sb, cb);
  const int j = bin.blend > 0 ? blend_pick(outcome, a.u, uniform()) : outcome;
  double st = 0, ct = 1;
  if (turns_) sincos_angle(bin_[std::size_t(j)].turn * (a.from_middle + bin.middle - bin_[std::size_t(j)].middle), st, ct);
  // Lifted lobes about the exit normal turned back by the turn: (sin, 0, cos) of alpha - turn.
  const Vec3 normal = lifted_ ? Vec3{a.sin_alpha * ct - a.cos_alpha * st, 0, a.cos_alpha * ct + a.sin_alpha * st} : Vec3{};
  Vec3 w = direction(j, normal, uniform);
  if (turns_) w = {ct * w.x + st * w.z, w.y, ct * w.z - st * w.x};  // turn_about_y, with sin and cos at hand
  // The frame turned by the azimuth about its z (e1, e2, f.z), written out by component: the
  // operator form costs 1-2% of a stride (bench/stride_cost).
  const Vec3 e1{cb * f.x.x + sb * f.y.x, cb * f.x.y + sb * f.y.y, cb * f.x.z + sb * f.y.z};
  const Vec3 e2{cb * f.y.x - sb * f.x.x, cb * f.y.y - sb * f.x.y, cb * f.y.z - sb * f.x.z};
  return {{a.sin_alpha * e1.x + a.cos_alpha * f.z.x, a.sin_alpha * e1.y + a.cos_alpha * f.z.y,
           a.sin_alpha * e1.z + a.cos_alpha * f.z.z},
          {w.x * e1.x + w.y * e2.x + w.z * f.z.x, w.x * e1.y + w.y * e2.y + w.z * f.z.y, w.x * e1.z + w.y * e2.z + w.z * f.z.z},
          kSmooth};
}

}  // namespace stf
