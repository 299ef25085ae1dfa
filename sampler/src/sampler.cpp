#include "stf/sampler.h"

#include <algorithm>
#include <cmath>

#include "stf/vmf.h"

namespace stf {

namespace {

// Index i with cdf[i] <= u < cdf[i + 1] among [first, last) (cdf non-decreasing, cdf[first]
// = 0), skipping zero-width entries; `remainder` is u's position inside it, in [0, 1).
int sample_cdf(const double* cdf, int n, double u, double& remainder) {
  double total = cdf[n];
  double target = u * total;
  int i = int(std::upper_bound(cdf, cdf + n + 1, target) - cdf) - 1;
  i = std::clamp(i, 0, n - 1);
  while (i > 0 && cdf[i + 1] == cdf[i]) --i;  // u at the very top: land on a non-empty entry
  double width = cdf[i + 1] - cdf[i];
  remainder = width > 0 ? std::clamp((target - cdf[i]) / width, 0.0, std::nextafter(1.0, 0.0)) : 0.0;
  return i;
}

Vec3 rotate_z(const Vec3& v, double c, double s) { return {c * v.x - s * v.y, s * v.x + c * v.y, v.z}; }

}  // namespace

ShellSampler::ShellSampler(StfModel model) : model_(std::move(model)) {
  const int bins = model_.bins();
  alpha_cdf_.assign(bins + 1, 0.0);
  for (int b = 0; b < bins; ++b) alpha_cdf_[b + 1] = alpha_cdf_[b] + model_.alpha_probability[b];
  if (model_.kind == ModelKind::kSh) {
    const int cells = 2 * model_.sh_nz * model_.sh_nz;
    cell_cdf_.assign(std::size_t(bins) * (cells + 1), 0.0);
    for (int b = 0; b < bins; ++b) {
      double* cdf = &cell_cdf_[std::size_t(b) * (cells + 1)];
      const float* table = &model_.sh_table[std::size_t(b) * cells];
      for (int c = 0; c < cells; ++c) cdf[c + 1] = cdf[c] + double(table[c]);  // equal areas
    }
  }
}

int ShellSampler::sample_alpha_bin(double u, double& remainder) const {
  return sample_cdf(alpha_cdf_.data(), model_.bins(), u, remainder);
}

Vec3 ShellSampler::sample_direction(int bin, double u2, double u3) const {
  if (model_.kind == ModelKind::kVmf) {
    // Pick a lobe by weight and reuse the rest of u2 for the lobe's own polar angle.
    const VmfLobe* lobes = &model_.vmf[std::size_t(bin) * model_.lobes];
    double u = u2;
    int k = 0;
    while (k + 1 < model_.lobes && (u >= lobes[k].weight || lobes[k].weight <= 0)) u -= lobes[k++].weight;
    double remainder = lobes[k].weight > 0 ? std::clamp(u / lobes[k].weight, 0.0, std::nextafter(1.0, 0.0)) : 0.0;
    return sample_vmf(lobes[k], remainder, u3);
  }
  // Tabulated SH: a cell by its mass, then uniform in it (uniform in z and phi is uniform in area).
  const int nz = model_.sh_nz, cells = 2 * nz * nz;
  double remainder;
  int c = sample_cdf(&cell_cdf_[std::size_t(bin) * (cells + 1)], cells, u2, remainder);
  int row = c / (2 * nz), col = c % (2 * nz);
  double z = -1 + (row + remainder) * 2.0 / nz;
  double phi = (col + u3) * kPi / nz;
  double rho = std::sqrt(std::max(0.0, 1 - z * z));
  return {rho * std::cos(phi), rho * std::sin(phi), z};
}

ExitSample ShellSampler::sample(double u0, double u1, double u2, double u3) const {
  double remainder;
  int bin = sample_alpha_bin(u0, remainder);
  double c0 = std::cos(model_.alpha_edges[bin]), c1 = std::cos(model_.alpha_edges[bin + 1]);
  double cos_alpha = c0 + remainder * (c1 - c0), sin_alpha = std::sqrt(std::max(0.0, 1 - cos_alpha * cos_alpha));
  double beta = 2 * kPi * u1, cb = std::cos(beta), sb = std::sin(beta);
  Vec3 local = sample_direction(bin, u2, u3);
  ExitSample s;
  s.point = {sin_alpha * cb, sin_alpha * sb, cos_alpha};
  s.direction = rotate_z(local, cb, sb);
  s.pdf = model_.alpha_probability[bin] / (2 * kPi * (c0 - c1)) * direction_pdf(bin, local);
  return s;
}

double ShellSampler::pdf(const Vec3& point, const Vec3& direction) const {
  const int bins = model_.bins();
  double z = std::clamp(point.z, -1.0, 1.0);
  double alpha = std::atan2(std::sqrt(point.x * point.x + point.y * point.y), z);
  int bin = std::clamp(int(alpha / kPi * bins), 0, bins - 1);
  double c0 = std::cos(model_.alpha_edges[bin]), c1 = std::cos(model_.alpha_edges[bin + 1]);
  double rho = std::sqrt(point.x * point.x + point.y * point.y);
  double cb = rho > 0 ? point.x / rho : 1, sb = rho > 0 ? point.y / rho : 0;
  Vec3 local = rotate_z(direction, cb, -sb);
  return model_.alpha_probability[bin] / (2 * kPi * (c0 - c1)) * direction_pdf(bin, local);
}

namespace {
struct Frame {
  Vec3 x, y, z;
  Vec3 to_world(const Vec3& v) const {
    return {v.x * x.x + v.y * y.x + v.z * z.x, v.x * x.y + v.y * y.y + v.z * z.y, v.x * x.z + v.y * y.z + v.z * z.z};
  }
  Vec3 to_local(const Vec3& v) const { return {dot(v, x), dot(v, y), dot(v, z)}; }
};
Frame frame_around(const Vec3& n) {
  Frame f;
  f.z = n;
  orthonormal_basis(n, f.x, f.y);
  return f;
}
}  // namespace

WorldExit ShellSampler::sample_world(const Vec3& position, const Vec3& direction, double radius, double u0,
                                     double u1, double u2, double u3) const {
  Frame f = frame_around(direction);
  ExitSample s = sample(u0, u1, u2, u3);
  Vec3 p = f.to_world(s.point);
  // The unit-sphere area measure scales by radius^2 on the sphere of that radius.
  return {{position.x + radius * p.x, position.y + radius * p.y, position.z + radius * p.z},
          f.to_world(s.direction), s.pdf / (radius * radius)};
}

double ShellSampler::pdf_world(const Vec3& position, const Vec3& direction, double radius, const Vec3& exit_point,
                               const Vec3& exit_direction) const {
  Frame f = frame_around(direction);
  Vec3 d{(exit_point.x - position.x) / radius, (exit_point.y - position.y) / radius, (exit_point.z - position.z) / radius};
  return pdf(f.to_local(d), f.to_local(exit_direction)) / (radius * radius);
}

}  // namespace stf
