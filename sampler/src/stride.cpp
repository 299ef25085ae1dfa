#include "stf/stride.h"

namespace stf {

namespace {

std::vector<double> outcome_weights(const StfModel& m) {
  std::vector<double> w;
  for (int b = 0; b < m.bins(); ++b) w.push_back(std::max(0.0, m.smooth_probability(b)));
  w.push_back(m.uncollided_probability());
  w.push_back(m.once_fraction);
  return w;
}

// The exact exit angle less the bin's middle at remainder r, and its derivative in r.
struct ExactAngle {
  double a0, a1, tilt, expm1_tilt;
  double offset(double r) const {
    const double u = tilt_quantile(tilt, expm1_tilt, r), c = std::cos(a0) + u * (std::cos(a1) - std::cos(a0));
    return std::acos(std::clamp(c, -1.0, 1.0)) - 0.5 * (a0 + a1);
  }
  double slope(double r) const {
    const double u = tilt_quantile(tilt, expm1_tilt, r), c = std::cos(a0) + u * (std::cos(a1) - std::cos(a0));
    const double du = std::abs(tilt) < kFlatTilt ? 1.0 : expm1_tilt / (tilt * (1 + r * expm1_tilt));
    return -(std::cos(a1) - std::cos(a0)) * du / std::sqrt(std::max(1e-300, 1 - c * c));
  }
};

// The interpolating polynomial of f at the Chebyshev points of [-1, 1], in powers of x.
template <int N, typename F>
void chebyshev_interpolant(F&& f, double (&power)[N]) {
  double value[N], cheb[N] = {};
  for (int k = 0; k < N; ++k) value[k] = f(std::cos(kPi * (k + 0.5) / N));
  for (int j = 0; j < N; ++j) {
    for (int k = 0; k < N; ++k) cheb[j] += value[k] * std::cos(kPi * j * (k + 0.5) / N);
    cheb[j] *= (j == 0 ? 1.0 : 2.0) / N;
  }
  // T_j in powers of x by T_{j+1} = 2 x T_j - T_{j-1}.
  double t_prev[N] = {1}, t_cur[N] = {0, 1};
  for (int i = 0; i < N; ++i) power[i] = 0;
  power[0] += cheb[0];
  if (N > 1) power[1] += cheb[1];
  for (int j = 2; j < N; ++j) {
    double t_next[N] = {};
    for (int i = 0; i < N; ++i) t_next[i] = (i > 0 ? 2 * t_cur[i - 1] : 0.0) - t_prev[i];
    for (int i = 0; i < N; ++i) t_prev[i] = t_cur[i], t_cur[i] = t_next[i], power[i] += cheb[j] * t_cur[i];
  }
}

}  // namespace

bool StrideForm::fit_angle(Bin& bin, double a0, double a1) {
  const ExactAngle exact{a0, a1, bin.tilt, bin.expm1_tilt};
  chebyshev_interpolant([&](double x) { return exact.offset(0.5 * (x + 1)); }, bin.angle);
  // Checked on a grid eight times finer than the points it interpolates.
  for (int k = 0; k <= 8 * (kAngleDegree + 1); ++k) {
    const double r = k / (8.0 * (kAngleDegree + 1)), x = 2 * r - 1;
    double dp = 0;  // d p / d x
    for (int i = kAngleDegree; i >= 1; --i) dp = dp * x + i * bin.angle[i];
    const double p = angle_polynomial(bin.angle, x);  // as the draw sums it
    if (std::abs(p - exact.offset(r)) > kAngleError || std::abs(2 * dp / exact.slope(r) - 1) > kAngleSlopeError)
      return false;
  }
  return true;
}

StrideForm::StrideForm(const StfModel& model, std::shared_ptr<const DrawTables> tables)
    : bins_(model.bins()), lobes_per_bin_(model.lobes), sh_(model.kind == ModelKind::kSh),
      turns_(!model.alpha_turn.empty()), lifted_(model.lifted), escape_probability_(model.escape_probability),
      outcomes_(outcome_weights(model)), sh_nz_(model.sh_nz),
      tables_(tables ? std::move(tables) : make_draw_tables(model)) {
  const StfModel& m = model;
  for (int b = 0; b < bins_; ++b) {
    const double a0 = m.alpha_edges[std::size_t(b)], a1 = m.alpha_edges[std::size_t(b) + 1];
    const double c0 = b == 0 ? 1.0 : std::cos(a0), c1 = b + 1 == bins_ ? -1.0 : std::cos(a1);
    // 1 - cos a = 2 sin^2(a / 2) and 1 + cos a = 2 cos^2(a / 2) keep their digits where cos a
    // is near 1 or -1.
    const double om0 = 2 * std::pow(std::sin(a0 / 2), 2), om1 = 2 * std::pow(std::sin(a1 / 2), 2);
    const double op0 = 2 * std::pow(std::cos(a0 / 2), 2), op1 = b + 1 == bins_ ? 0.0 : 2 * std::pow(std::cos(a1 / 2), 2);
    const double middle = 0.5 * (a0 + a1), tilt = m.tilt(b);
    bin_.push_back({c0, c1 - c0, om0, om1 - om0, op0, op1 - op0, tilt, std::expm1(tilt), 1 / tilt, middle, std::cos(middle),
                    std::sin(middle), turns_ ? m.alpha_turn[std::size_t(b)] : 0.0, m.blend_width(b), 1 / (c1 - c0)});
    // The bins at the poles keep the quantile: alpha is a square root of the area there.
    bin_.back().exact = b == 0 || b + 1 == bins_ || !fit_angle(bin_.back(), a0, a1);
  }
  for (const VmfLobe& l : m.vmf) lobe_.emplace_back(l);
}

StrideForm::ExitAngle StrideForm::exit_angle(const Bin& bin, double r) const {
  ExitAngle a;
  if (!bin.exact) {
    // The polynomial, then the sine and cosine of the offset by their series (|offset| is at
    // most half a bin: 0.3 rad is a bin wider than any model's, where the terms left out are
    // below 1e-17).
    const double d = angle_polynomial(bin.angle, 2 * r - 1);
    double sd, cd;
    sincos_angle(d, sd, cd);
    a.cos_alpha = bin.cos_middle * cd - bin.sin_middle * sd;
    a.sin_alpha = bin.sin_middle * cd + bin.cos_middle * sd;
    a.u = std::clamp((a.cos_alpha - bin.c0) * bin.inv_dc, 0.0, 1.0);
    a.from_middle = d;
    return a;
  }
  // tilt_quantile, with log for log1p where |tilt| >= 1e-3 (the rounding of 1 + x then costs u
  // at most 1e-13 relative) and a product for the division.
  if (std::abs(bin.tilt) < 1e-3) {
    a.u = tilt_quantile(bin.tilt, bin.expm1_tilt, r);
  } else {
    a.u = std::clamp(std::log(1 + r * bin.expm1_tilt) * bin.inv_tilt, 0.0, 1.0);
  }
  a.cos_alpha = bin.c0 + a.u * bin.dc;
  a.sin_alpha = std::sqrt(std::max(0.0, (bin.om0 + a.u * bin.dom) * (bin.op0 + a.u * bin.dop)));
  if (turns_) {
    // alpha - middle = 2 atan(sin d / (1 + cos d)), d's sine and cosine by the angle-difference
    // formulas: no cancellation, as |d| is at most half a bin.
    const double s = a.sin_alpha * bin.cos_middle - a.cos_alpha * bin.sin_middle;
    const double c = a.cos_alpha * bin.cos_middle + a.sin_alpha * bin.sin_middle;
    a.from_middle = 2 * atan_near_zero(s / (1 + c));
  }
  return a;
}

int StrideForm::blend_pick(int b, double u, double v) const {
  // StfModel::blend_weights's hats, picked by v.
  int blend_bins[2 * StfModel::kMaxBlend + 1];
  double weights[2 * StfModel::kMaxBlend + 1];
  const int n = blend_hats(b, u, bin_[std::size_t(b)].blend, bins_, blend_bins, weights);
  int k = 0;
  double below = 0;
  while (k + 1 < n && v >= below + weights[k]) below += weights[k++];
  return blend_bins[k];
}

Vec3 StrideForm::sh_direction(int bin, double u, double v) const {
  double in_cell;
  const int cell = tables_->cells[std::size_t(bin)].sample(u, in_cell);
  return equal_area_direction(sh_nz_, cell, in_cell, v);
}

Stride StrideForm::once_scattered(double r, double u1, double u2, double u3) const {
  Stride s;
  tables_->once.sample(r, u1, u2, u3, s.point, s.direction);
  s.component = kOnceScattered;
  return s;
}

}  // namespace stf
