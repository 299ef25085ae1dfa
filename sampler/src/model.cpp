#include "stf/model.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "stf/hemisphere.h"
#include "stf/math.h"
#include "stf/pack.h"
#include "stf/quadrature.h"
#include "stf/sh.h"
#include "stf/tilt.h"

namespace stf {

int equal_area_cell(int nz, const Vec3& w) {
  int row = std::clamp(int((w.z + 1) * 0.5 * nz), 0, nz - 1);
  double phi = std::atan2(w.y, w.x);
  phi = phi < 0 ? phi + 2 * kPi : phi;
  int col = std::clamp(int(phi / (2 * kPi) * (2 * nz)), 0, 2 * nz - 1);
  return row * 2 * nz + col;
}

Vec3 equal_area_direction(int nz, int cell, double in_cell, double v) {
  const int nphi = 2 * nz;
  const double z = -1 + (cell / nphi + in_cell) * 2.0 / nz, rho = std::sqrt(std::max(0.0, 1 - z * z));
  double sp, cp;
  sincos_2pi((cell % nphi + v) / nphi, sp, cp);
  return {rho * cp, rho * sp, z};
}

double StfModel::outward_factor(int bin, const Vec3& w) const {
  return hemispherical ? OutwardBin(alpha_edges[std::size_t(bin)], alpha_edges[std::size_t(bin) + 1])(w) : 1.0;
}

double StfModel::direction_pdf(int bin, const Vec3& w, const Vec3& normal) const {
  if (kind != ModelKind::kVmf || !lifted) return direction_pdf(bin, w);
  return lifted_pdf(w, normal, [&](const Vec3& v) {
    double p = 0;
    for (const VmfLobe& l : lobes_of(bin)) p += l.weight * vmf_pdf(l.kappa, dot(l.mean, v));
    return p;
  });
}

double StfModel::direction_pdf(int bin, const Vec3& w) const {
  if (kind == ModelKind::kVmf && lifted) return direction_pdf(bin, w, middle_normal(bin));
  if (kind == ModelKind::kVmf) {
    double p = 0;
    const BinSlice<const double> norm = hemispherical ? bin_slice(lobe_norm, bin, lobes) : BinSlice<const double>();
    const BinSlice<const VmfLobe> bin_lobes = lobes_of(bin);
    for (int k = 0; k < lobes; ++k) {
      const VmfLobe& l = bin_lobes[std::size_t(k)];
      p += l.weight * vmf_pdf(l.kappa, dot(l.mean, w)) / (hemispherical ? norm[std::size_t(k)] : 1.0);
    }
    return p * outward_factor(bin, w);
  }
  const std::size_t cells = std::size_t(2) * sh_nz * sh_nz;
  return sh_table[bin * cells + equal_area_cell(sh_nz, w)];
}

namespace {

// E[factor(w)] under a lobe: Gauss-Legendre over the lobe's own quantile of cos(theta) (so a
// narrow lobe needs no finer rule than a broad one) times a uniform azimuth rule.
constexpr int kAzimuths = 32;

// cos and sin of the azimuth rule's angles, computed once (a pack's models ask for them
// 2048 times a lobe).
struct AzimuthRule {
  double cos[kAzimuths], sin[kAzimuths];
  AzimuthRule() {
    for (int a = 0; a < kAzimuths; ++a) cos[a] = std::cos(2 * kPi * (a + 0.5) / kAzimuths), sin[a] = std::sin(2 * kPi * (a + 0.5) / kAzimuths);
  }
};

template <typename Factor>
double mean_under_lobe(const VmfLobe& l, Factor factor) {
  constexpr int kPanels = 8;
  static const AzimuthRule rule;
  const Frame frame = Frame::around(l.mean);
  double sum = 0;
  for (int p = 0; p < kPanels; ++p)
    sum += gauss8(
        [&](double u) {
          const double c = sample_vmf_cos(l.kappa, u), s = std::sqrt(std::max(0.0, 1 - c * c));
          double ring = 0;
          for (int a = 0; a < kAzimuths; ++a) ring += factor(frame.to_world({s * rule.cos[a], s * rule.sin[a], c}));
          return ring / kAzimuths;
        },
        double(p) / kPanels, double(p + 1) / kPanels);
  return sum;
}

}  // namespace

void StfModel::rebuild_lobe_norms() {
  lobe_norm.assign(vmf.size(), 1.0);
  if (!hemispherical || kind != ModelKind::kVmf) return;
  for (int b = 0; b < bins(); ++b) {
    const OutwardBin factor(alpha_edges[std::size_t(b)], alpha_edges[std::size_t(b) + 1]);
    const BinSlice<VmfLobe> l = bin_slice(vmf, b, lobes);
    const BinSlice<double> z = bin_slice(lobe_norm, b, lobes);
    // A lobe turned (all but a millionth of it) below the bin's tangent planes holds no
    // density worth a draw that waits on it: it is dropped (its weight goes to the others) and
    // made uniform, so that even a rounding that picks it terminates; a bin left with none is
    // uniform.
    double kept = 0;
    for (int k = 0; k < lobes; ++k) {
      z[k] = mean_under_lobe(l[k], factor);
      if (!(z[k] > 1e-6)) {
        l[k] = {0, 0, {0, 0, 1}};
        z[k] = mean_under_lobe(l[k], factor);
      }
      kept += l[k].weight;
    }
    if (kept <= 0) {
      l[0] = {1, 0, {0, 0, 1}};
      z[0] = mean_under_lobe(l[0], factor);
      kept = 1;
    }
    for (int k = 0; k < lobes; ++k) l[k].weight /= kept;
  }
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

namespace {
bool finite_in(double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; }
}  // namespace

int blend_hats(int b, double u, int width, int bins, int* blend_bins, double* weights) {
  if (width <= 0) {
    blend_bins[0] = b, weights[0] = 1;
    return 1;
  }
  const double x = b + u, h = width;
  int n = 0;
  double total = 0;
  for (int j = std::max(0, b - width); j <= std::min(bins - 1, b + width); ++j) {
    const double k = 1 - std::abs(x - j - 0.5) / h;
    if (k <= 0) continue;
    blend_bins[n] = j, weights[n] = k, total += k, ++n;
  }
  for (int i = 0; i < n; ++i) weights[i] /= total;
  return n;
}

int StfModel::blend_weights(int b, double u, int* blend_bins, double* weights) const {
  return blend_hats(b, u, blend_width(b), this->bins(), blend_bins, weights);
}

std::string model_size_error(bool sh, double bins, double size, double nz, double degree) {
  if (!(bins >= 1 && bins <= kMaxModelBins)) return "alpha bins out of range [1, " + std::to_string(kMaxModelBins) + "]";
  if (!sh) return size >= 1 && size <= kMaxLobes ? "" : "vMF lobe count out of range [1, " + std::to_string(kMaxLobes) + "]";
  if (!(size >= 0 && size <= kMaxBandLimit && nz >= 1 && nz <= kMaxShNz && degree >= -1 && degree <= kMaxAlphaDegree))
    return "SH band limit, table rows or alpha degree out of range ([0, " + std::to_string(kMaxBandLimit) + "], [1, " +
           std::to_string(kMaxShNz) + "], [-1, " + std::to_string(kMaxAlphaDegree) + "])";
  if (bins * nz * nz * 2 > kMaxShTableCells) return "SH tables of all alpha bins would exceed 2^27 cells";
  return "";
}

std::string draw_error(const StfModel& m) {
  if (m.once_fraction > 0 && !(m.tau <= kMaxOnceTau))
    return "a once-scattered part at tau above " + std::to_string(int(kMaxOnceTau)) + " cannot be drawn from";
  if (m.once_fraction < 1 && m.alpha_probability.size() > 0) {
    double total = 0;
    for (double p : m.alpha_probability) total += p;
    if (!(total > 0)) return "alpha probabilities are all 0: nothing to draw";
  }
  return "";
}

namespace {

std::string lobes_error(const StfModel& m) {
  if (m.lobes < 1 || m.vmf.size() != std::size_t(m.bins()) * m.lobes) return "vMF lobes of the wrong count";
  for (int b = 0; b < m.bins(); ++b) {
    double weights = 0;
    for (int k = 0; k < m.lobes; ++k) {
      const VmfLobe& l = m.lobes_of(b)[std::size_t(k)];
      if (!finite_in(l.weight, 0, 1) || !finite_in(l.kappa, 0, kMaxKappa))
        return "vMF weight or kappa (/vmf/weight, /vmf/kappa) out of range (weight in [0, 1], kappa in [0, " +
               std::to_string(kMaxKappa) + "]; bin " + std::to_string(b) + ", lobe " + std::to_string(k) + ")";
      if (!(std::abs(length(l.mean) - 1) < 1e-6))
        return "vMF mean direction (/vmf/mean) is not a unit vector (bin " + std::to_string(b) + ", lobe " + std::to_string(k) + ")";
      weights += l.weight;
    }
    if (std::abs(weights - 1) > 1e-6) return "vMF weights (/vmf/weight) of bin " + std::to_string(b) + " do not sum to 1";
  }
  return "";
}

}  // namespace

std::string model_error(const StfModel& m) {
  const int bins = m.bins();
  if (bins < 1) return "no alpha bins";
  const bool sh = m.kind == ModelKind::kSh;
  if (std::string why = model_size_error(sh, bins, sh ? m.band_limit : m.lobes, sh ? m.sh_nz : 1, sh ? m.alpha_degree : -1);
      !why.empty())
    return why;
  if (!m.has_medium()) {
    if (!(std::isnan(m.albedo) && std::isnan(m.g))) return "medium incomplete (tau, albedo and g, or none of them)";
    if (m.once_fraction != 0) return "a model without a medium has no once-scattered part";
  } else if (!(finite_in(m.tau, 0, kMaxModelTau) && m.tau > 0 && finite_in(m.albedo, 0, 1) && m.g > -1 && m.g < 1)) {
    return "medium out of range (tau in (0, 1e7], albedo in [0, 1], g in (-1, 1))";
  }
  if (!finite_in(m.escape_probability, 0, 1) || !finite_in(m.absorbed_fraction, 0, 1) ||
      !finite_in(m.truncated_fraction, 0, 1))
    return "escape, absorbed and truncated fractions must be in [0, 1]";
  if (int(m.alpha_edges.size()) != bins + 1 || int(m.status.size()) != bins) return "alpha bins of unequal counts";
  if (m.alpha_edges.front() != 0 || std::abs(m.alpha_edges.back() - kPi) > 1e-9) return "alpha edges must run from 0 to pi";
  double total = 0;
  for (int b = 0; b < bins; ++b) {
    if (!(m.alpha_edges[b + 1] - m.alpha_edges[b] >= kMinAlphaBinWidth))
      return "alpha edges must increase by at least 1e-6 rad (bin " + std::to_string(b) + ")";
    if (!finite_in(m.alpha_probability[b], 0, 1))
      return "alpha probability (/alpha/probability) negative or not finite (bin " + std::to_string(b) + ")";
    if (int(m.status[b]) < 0 || int(m.status[b]) > 2) return "bin status (/alpha/status) out of range (bin " + std::to_string(b) + ")";
    total += m.alpha_probability[b];
  }
  if (std::abs(total - 1) > 1e-6) return "alpha probabilities (/alpha/probability) do not sum to 1";
  if (!finite_in(m.once_fraction, 0, 1)) return "once-scattered fraction must be in [0, 1]";
  if (!m.alpha_tilt.empty() && int(m.alpha_tilt.size()) != bins) return "alpha tilts of the wrong count";
  if (m.alpha_blend < 0 || m.alpha_blend > StfModel::kMaxBlend) return "alpha blend out of range [0, 3]";
  if (m.lifted && (m.hemispherical || m.kind != ModelKind::kVmf)) return "lifted lobes are vMF lobes, and not hemispherical ones";
  if (!m.alpha_blend_width.empty() && int(m.alpha_blend_width.size()) != bins) return "alpha blend widths of the wrong count";
  for (int h : m.alpha_blend_width)
    if (h < 0 || h > m.alpha_blend) return "alpha blend width (/alpha/blend) out of range [0, alpha_blend]";
  for (double t : m.alpha_tilt)
    if (!finite_in(t, -kMaxTilt, kMaxTilt)) return "alpha tilt (/alpha/tilt) out of range [-40, 40]";
  if (!m.alpha_turn.empty() && int(m.alpha_turn.size()) != bins) return "alpha turns of the wrong count";
  for (double r : m.alpha_turn)
    if (!finite_in(r, -StfModel::kMaxTurn, StfModel::kMaxTurn)) return "alpha turn (/alpha/turn) out of range [-8, 8]";
  if (!finite_in(m.uncollided_fraction, 0, m.alpha_probability[0] * (1 + 1e-9)))
    return "uncollided fraction must be in [0, alpha probability of bin 0]";
  if (m.kind == ModelKind::kVmf) {
    if (std::string why = lobes_error(m); !why.empty()) return why;
    return draw_error(m);
  }
  const std::size_t count = std::size_t(sh_count(m.band_limit));
  if (m.band_limit < 0 || m.sh.size() != std::size_t(bins) * count) return "SH coefficients of the wrong count";
  for (const auto* coefficients : {&m.sh, &m.sh_chebyshev})
    for (double c : *coefficients)
      if (!std::isfinite(c)) return "SH coefficient (/sh/coefficients or /sh/chebyshev) not finite";
  for (float v : m.sh_table)
    if (!std::isfinite(v)) return "SH density not finite";
  return draw_error(m);
}

std::int64_t StfModel::packed_bytes() const { return 32 + record_bytes(*this, 0); }

}  // namespace stf
