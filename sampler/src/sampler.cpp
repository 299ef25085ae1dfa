#include "stf/sampler.h"

#include <algorithm>
#include <cmath>

#include "stf/hemisphere.h"
#include "stf/math.h"
#include "stf/tilt.h"
#include "stf/vmf.h"

namespace stf {

namespace {

Vec3 rotate_z(const Vec3& v, double c, double s) { return {c * v.x - s * v.y, s * v.x + c * v.y, v.z}; }

}  // namespace

ShellSampler::ShellSampler(StfModel model, std::shared_ptr<const DrawTables> tables) : model_(std::move(model)) {
  const int bins = model_.bins();
  alpha_ = AliasTable(model_.alpha_probability);
  for (double a : model_.alpha_edges) cos_edges_.push_back(std::cos(a));
  cos_edges_.front() = 1, cos_edges_.back() = -1;
  for (int b = 0; b < bins; ++b) tilt_expm1_.push_back(std::expm1(model_.tilt(b)));
  if (model_.hemispherical && model_.lobe_norm.size() != model_.vmf.size()) model_.rebuild_lobe_norms();
  tables_ = tables ? std::move(tables) : make_draw_tables(model_);
  form_ = StrideForm(model_, tables_);
  for (std::size_t i = 0; i < model_.vmf.size(); ++i) {
    const VmfLobe& l = model_.vmf[i];
    Lobe c;
    static_cast<VmfFrame&>(c) = VmfFrame(l);
    c.weight = l.weight;
    // A hemispherical lobe is renormalised after its outward factor: its density at the mean
    // carries 1 / lobe_norm.
    c.norm = vmf_pdf(l.kappa, 1.0) / (model_.hemispherical ? model_.lobe_norm[i] : 1.0);
    lobes_.push_back(c);
  }
}

double ShellSampler::lobe_pdf(const Lobe& l, const Vec3& w) const {
  return l.norm * std::exp(l.kappa * (dot(l.mean(), w) - 1));
}

int ShellSampler::alpha_bin_of(double cos_alpha) const {
  // First edge below cos_alpha: bins hold cos(alpha) in (cos a1, cos a0].
  auto it = std::lower_bound(cos_edges_.begin() + 1, cos_edges_.end() - 1, cos_alpha,
                             [](double edge, double z) { return edge >= z; });
  return int(it - cos_edges_.begin()) - 1;
}

Vec3 ShellSampler::lift_normal(double alpha, double turn) const {
  return model_.lifted ? Vec3{std::sin(alpha - turn), 0, std::cos(alpha - turn)} : Vec3{0, 0, 1};
}

double ShellSampler::direction_pdf(int bin, const Vec3& w) const {
  return direction_pdf(bin, w, model_.lifted ? model_.middle_normal(bin) : Vec3{0, 0, 1});
}

double ShellSampler::direction_pdf(int bin, const Vec3& w, const Vec3& normal) const {
  if (model_.kind == ModelKind::kSh) return model_.direction_pdf(bin, w);
  auto lobes = [&](const Vec3& v) {
    double p = 0;
    for (const Lobe& l : bin_slice(lobes_, bin, model_.lobes)) p += l.weight * lobe_pdf(l, v);
    return p;
  };
  if (model_.lifted) return lifted_pdf(w, normal, lobes);
  return model_.hemispherical ? lobes(w) * tables_->outward[std::size_t(bin)](w) : lobes(w);
}

int ShellSampler::sample_alpha_bin(double u, double& remainder) const { return alpha_.sample(u, remainder); }

Vec3 ShellSampler::sample_direction(int bin, double u2, double u3) const {
  return sample_direction(bin, u2, u3, model_.lifted ? model_.middle_normal(bin) : Vec3{0, 0, 1});
}

Vec3 ShellSampler::sample_direction(int bin, double u2, double u3, const Vec3& normal) const {
  if (model_.kind == ModelKind::kVmf) {
    // Pick a lobe by weight and reuse the rest of u2 for the lobe's own polar angle (a lobe of
    // zero weight, picked by rounding, is uniform).
    const BinSlice<const double> sums = tables_->lobe_sums(bin);
    const int k = pick_lobe(sums.begin(), model_.lobes, u2);
    const Lobe& l = bin_slice(lobes_, bin, model_.lobes)[std::size_t(k)];
    const double below = k > 0 ? sums[std::size_t(k) - 1] : 0.0;
    double remainder = l.weight > 0 ? std::clamp((u2 - below) / l.weight, 0.0, std::nextafter(1.0, 0.0)) : 0.0;
    Vec3 w = l.direction(remainder, u3);
    if (model_.lifted) return lift_direction(w, normal);
    if (!model_.hemispherical) return w;
    // The lobe times the bin's outward factor (<= 1): a lobe draw kept with that probability;
    // the acceptance and any retries come from a stream seeded from (u2, u3).
    RetryStream retry(u2, u3, 0.5, 0.25);
    const OutwardBin& factor = tables_->outward[std::size_t(bin)];
    while (retry.uniform() >= factor(w)) w = l.direction(retry.uniform(), retry.uniform());
    return w;
  }
  // Tabulated SH: a cell by mass, then uniform in the cell. What is left of u2 places z, u3 phi.
  double in_cell;
  const int cell = tables_->cells[std::size_t(bin)].sample(u2, in_cell);
  return equal_area_direction(model_.sh_nz, cell, in_cell, u3);
}

ExitSample ShellSampler::draw(double u0, double u1, double u2, double u3, int& bin, Vec3& local) const {
  ExitSample s;
  const double once = model_.once_fraction;
  if (u0 < once) {
    tables_->once.sample(u0 / once, u1, u2, u3, s.point, s.direction);
    s.pdf = once;
    s.component = kOnceScattered;
    bin = -1;
    return s;
  }
  double remainder;
  bin = sample_alpha_bin(once > 0 ? std::min((u0 - once) / (1 - once), std::nextafter(1.0, 0.0)) : u0, remainder);
  if (bin == 0) {  // the uncollided delta is part of bin 0
    const double share = model_.uncollided_share_of_bin0();
    if (remainder < share) {
      s.point = s.direction = {0, 0, 1};
      s.pdf = model_.uncollided_probability();
      s.component = kUncollided;
      bin = -1;
      return s;
    }
    remainder = std::min((remainder - share) / (1 - share), 1.0);
  }
  double c0 = cos_edges_[bin], c1 = cos_edges_[bin + 1];
  const double u = tilt_quantile(model_.tilt(bin), tilt_expm1_[std::size_t(bin)], remainder);
  double cos_alpha = c0 + u * (c1 - c0), sin_alpha = std::sqrt(std::max(0.0, 1 - cos_alpha * cos_alpha));
  double cb, sb;
  sincos_2pi(u1, sb, cb);  // beta = 2 pi u1
  // A blended bin: one of the blended densities by weight, picked with u2 and its remainder
  // reused for the direction.
  int blend_bins[2 * StfModel::kMaxBlend + 1];
  double weights[2 * StfModel::kMaxBlend + 1];
  const int n = model_.blend_weights(bin, u, blend_bins, weights);
  int k = 0;
  double below = 0;
  while (k + 1 < n && u2 >= below + weights[k]) below += weights[k++];
  const double rest = n > 1 ? std::clamp((u2 - below) / weights[k], 0.0, std::nextafter(1.0, 0.0)) : u2;
  const double alpha = model_.lifted || !model_.alpha_turn.empty() ? std::atan2(sin_alpha, cos_alpha) : 0.0;
  const double turn = model_.alpha_turn.empty() ? 0.0 : model_.turn_angle(blend_bins[k], alpha);
  local = sample_direction(blend_bins[k], rest, u3, lift_normal(alpha, turn));
  if (!model_.alpha_turn.empty()) local = turn_about_y(local, turn);
  s.point = {sin_alpha * cb, sin_alpha * sb, cos_alpha};
  s.direction = rotate_z(local, cb, sb);
  return s;
}

ExitSample ShellSampler::sample(double u0, double u1, double u2, double u3) const {
  int bin;
  Vec3 local;
  ExitSample s = draw(u0, u1, u2, u3, bin, local);
  if (bin >= 0) s.pdf = smooth_pdf(bin, s.point.z, local);
  return s;
}

// The bin of `point` (unit sphere, local frame) and `direction` in the point's x-z frame (the
// azimuth beta turned back).
int ShellSampler::exit_frame(const Vec3& point, const Vec3& direction, Vec3& local) const {
  const double rho = std::sqrt(point.x * point.x + point.y * point.y);
  const double cb = rho > 0 ? point.x / rho : 1, sb = rho > 0 ? point.y / rho : 0;
  local = rotate_z(direction, cb, -sb);
  return alpha_bin_of(std::clamp(point.z, -1.0, 1.0));
}

double ShellSampler::pdf(const Vec3& point, const Vec3& direction) const {
  Vec3 local;
  const int bin = exit_frame(point, direction, local);
  return smooth_pdf(bin, point.z, local);
}

double ShellSampler::exit_direction_pdf(const Vec3& point, const Vec3& direction) const {
  Vec3 local;
  const int bin = exit_frame(point, direction, local);
  const double c0 = cos_edges_[bin], c1 = cos_edges_[bin + 1];
  return exit_direction_pdf(bin, point.z, std::clamp((c0 - point.z) / (c0 - c1), 0.0, 1.0), local);
}

double ShellSampler::exit_direction_pdf_world(const Vec3& position, const Vec3& direction, double radius,
                                              const Vec3& exit_point, const Vec3& exit_direction) const {
  const Frame f = Frame::around(direction);
  return exit_direction_pdf(f.to_local((exit_point - position) / radius), f.to_local(exit_direction));
}

double ShellSampler::smooth_pdf(int bin, double cos_alpha, const Vec3& local) const {
  const double c0 = cos_edges_[bin], c1 = cos_edges_[bin + 1];
  const double u = std::clamp((c0 - cos_alpha) / (c0 - c1), 0.0, 1.0);
  const double point = model_.smooth_probability(bin) / (2 * kPi * (c0 - c1)) * tilt_density(model_.tilt(bin), u);
  return point * exit_direction_pdf(bin, cos_alpha, u, local);
}

double ShellSampler::exit_direction_pdf(int bin, double cos_alpha, double u, const Vec3& local) const {
  int blend_bins[2 * StfModel::kMaxBlend + 1];
  double weights[2 * StfModel::kMaxBlend + 1];
  const int n = model_.blend_weights(bin, u, blend_bins, weights);
  double direction = 0;
  if (model_.alpha_turn.empty() && !model_.lifted) {
    for (int k = 0; k < n; ++k) direction += weights[k] * direction_pdf(blend_bins[k], local);
    return direction;
  }
  // Each blended bin's density turned to this exit angle (StfModel::alpha_turn), its lifted lobes
  // about the exit normal turned back with it.
  const double alpha = std::atan2(std::sqrt(std::max(0.0, 1 - cos_alpha * cos_alpha)), cos_alpha);
  for (int k = 0; k < n; ++k) {
    const double turn = model_.alpha_turn.empty() ? 0.0 : model_.turn_angle(blend_bins[k], alpha);
    direction += weights[k] * direction_pdf(blend_bins[k], model_.alpha_turn.empty() ? local : turn_about_y(local, -turn),
                                            lift_normal(alpha, turn));
  }
  return direction;
}

WorldExit ShellSampler::to_world(const Vec3& position, const Vec3& direction, double radius,
                                  const ExitSample& s) const {
  const Frame f = Frame::around(direction);
  // The unit-sphere area measure scales by radius^2 on the sphere of that radius; a discrete
  // probability does not.
  return {position + radius * f.to_world(s.point), f.to_world(s.direction),
          s.component == kSmooth ? s.pdf / (radius * radius) : s.pdf, s.component};
}

WorldExit ShellSampler::sample_world(const Vec3& position, const Vec3& direction, double radius, double u0,
                                     double u1, double u2, double u3) const {
  return to_world(position, direction, radius, sample(u0, u1, u2, u3));
}

WorldExit ShellSampler::jump(const Vec3& position, const Vec3& direction, double radius, double u0, double u1,
                             double u2, double u3) const {
  const double first[4] = {u0, u1, u2, u3};
  RetryStream more(u0, u1, u2, u3);
  int taken = 0;
  return jump(position, direction, radius, [&] { return taken < 4 ? first[taken++] : more.uniform(); });
}

double ShellSampler::pdf_world(const Vec3& position, const Vec3& direction, double radius, const Vec3& exit_point,
                               const Vec3& exit_direction) const {
  const Frame f = Frame::around(direction);
  return pdf(f.to_local((exit_point - position) / radius), f.to_local(exit_direction)) / (radius * radius);
}

}  // namespace stf
