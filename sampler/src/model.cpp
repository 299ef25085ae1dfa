#include "stf/model.h"

#include <algorithm>
#include <cmath>

#include "stf/pack.h"
#include "stf/sh.h"

namespace stf {

int equal_area_cell(int nz, const Vec3& w) {
  int row = std::clamp(int((w.z + 1) * 0.5 * nz), 0, nz - 1);
  double phi = std::atan2(w.y, w.x);
  phi = phi < 0 ? phi + 2 * kPi : phi;
  int col = std::clamp(int(phi / (2 * kPi) * (2 * nz)), 0, 2 * nz - 1);
  return row * 2 * nz + col;
}

double StfModel::direction_pdf(int bin, const Vec3& w) const {
  if (kind == ModelKind::kVmf) {
    double p = 0;
    for (int k = 0; k < lobes; ++k) {
      const VmfLobe& l = vmf[std::size_t(bin) * lobes + k];
      p += l.weight * vmf_pdf(l.kappa, dot(l.mean, w));
    }
    return p;
  }
  const std::size_t cells = std::size_t(2) * sh_nz * sh_nz;
  return sh_table[bin * cells + equal_area_cell(sh_nz, w)];
}

void StfModel::rebuild_sh_tables() {
  const int nz = sh_nz, nphi = 2 * sh_nz, count = sh_count(band_limit);
  const double cell_area = 4 * kPi / (double(nz) * nphi);
  sh_table.assign(std::size_t(bins()) * nz * nphi, 0.0f);
  std::vector<double> basis(std::size_t(nz) * nphi * count);
  for (int r = 0; r < nz; ++r) {
    double z = -1 + (2 * r + 1.0) / nz, rho = std::sqrt(std::max(0.0, 1 - z * z));
    for (int c = 0; c < nphi; ++c) {
      double phi = 2 * kPi * (c + 0.5) / nphi;
      sh_basis(band_limit, {rho * std::cos(phi), rho * std::sin(phi), z},
               &basis[(std::size_t(r) * nphi + c) * count]);
    }
  }
  for (int b = 0; b < bins(); ++b) {
    const double* coef = &sh[std::size_t(b) * count];
    float* table = &sh_table[std::size_t(b) * nz * nphi];
    double total = 0;
    for (int i = 0; i < nz * nphi; ++i) {
      double v = 0;
      for (int j = 0; j < count; ++j) v += coef[j] * basis[std::size_t(i) * count + j];
      v = std::max(v, 0.0);
      table[i] = float(v);
      total += double(table[i]) * cell_area;
    }
    // Renormalise; a density clamped to nothing (cannot happen for a_00 > 0) falls back to
    // uniform rather than NaN.
    for (int i = 0; i < nz * nphi; ++i)
      table[i] = total > 0 ? float(table[i] / total) : float(1 / (4 * kPi));
  }
}

std::int64_t StfModel::packed_bytes() const { return 32 + record_bytes(*this, 0); }

}  // namespace stf
