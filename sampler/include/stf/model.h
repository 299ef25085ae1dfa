// A fitted shell transport function: what `stf fit` produces and a renderer samples.
//
// Per alpha bin (exit-point angle alpha, linear bins on [0, pi]) a density over exit
// directions w' per steradian, in the frame where the start direction is +z and the exit
// point lies in the x-z plane (x >= 0); across bins the alpha marginal; and the escape
// probability the renderer multiplies into its throughput.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "stf/vec3.h"
#include "stf/vmf.h"

namespace stf {

enum class ModelKind { kVmf, kSh };

// Which part of the exit distribution drew a sample.
enum Component : int { kSmooth = 0, kUncollided = 1, kOnceScattered = 2 };

// Bin b's `per` entries of an array laid out [bins * per] (the sampler's headers stay C++17,
// so no std::span).
template <typename T>
struct BinSlice {
  T* first = nullptr;
  std::size_t count = 0;
  T* begin() const { return first; }
  T* end() const { return first + count; }
  std::size_t size() const { return count; }
  T& operator[](std::size_t k) const { return first[k]; }
};
template <typename T>
BinSlice<T> bin_slice(std::vector<T>& v, int b, int per) {
  return {v.data() + std::size_t(b) * std::size_t(per), std::size_t(per)};
}
template <typename T>
BinSlice<const T> bin_slice(const std::vector<T>& v, int b, int per) {
  return {v.data() + std::size_t(b) * std::size_t(per), std::size_t(per)};
}

// How the direction model of one alpha bin came about.
enum class BinStatus : std::int32_t {
  kFitted = 0,    // fitted to the bin's own escapes
  kBorrowed = 1,  // too few escapes: copied from the nearest fitted bin
  kEmpty = 2,     // no bin has escapes (a model of an all-absorbing medium): uniform
};

struct StfModel {
  ModelKind kind = ModelKind::kVmf;
  // The medium (of the source table) and its dimensionless numbers; all NaN in a model of a
  // table that named no medium (such a model has no once-scattered part and cannot be packed).
  double sigma_s = 0, sigma_a = 0, g = 0, radius = 1, tau = 0, albedo = 0;
  bool has_medium() const { return !std::isnan(tau); }
  double escape_probability = 0, absorbed_fraction = 0, truncated_fraction = 0;
  // Share of the escapes that collided exactly once (format version 3): drawn exactly from the
  // medium's tau and g (stf/once_scattered.h), never fitted. Everything below describes the
  // other escapes, the "rest", as shares of them: the whole exit distribution is
  //   once_fraction * (once scattered) + (1 - once_fraction) * (rest).
  double once_fraction = 0;
  // Share of the rest that left without any collision: exactly at alpha = 0 heading +z (a
  // delta, not part of any fitted density). It is included in alpha_probability[0]; the
  // direction model of bin 0 describes the rest of that bin.
  double uncollided_fraction = 0;

  std::vector<double> alpha_edges;        // [bins + 1], 0 .. pi
  std::vector<double> alpha_probability;  // [bins], sums to 1: P(exit point in bin)
  // Inside bin b the smooth part's exit points have density tilt_density(alpha_tilt[b], u)
  // in u, the bin's area fraction from its lower edge (stf/tilt.h); empty: uniform in area
  // (format versions before 4).
  std::vector<double> alpha_tilt;
  // Blended bins (format version 4): at area fraction u of bin b, at x = b + u in bin units,
  // the smooth part's direction density is sum_j k_j p_j over the bins j with k_j = 1 - |x -
  // j - 1/2| / h > 0, normalised to sum 1, h = blend_width(b). 0: no blending; 1: the densities
  // change linearly between neighbouring bin centres (at u = 1/2 the bin's own alone); 2, 3:
  // smoothed over more bins. blend_weights() gives the bins and weights.
  int alpha_blend = 0;
  static constexpr int kMaxBlend = 3;
  // Widths per bin (format version 6): h = alpha_blend_width[b] in bin b, each at most
  // alpha_blend (the widest). Near the axis of a forward medium the direction density changes
  // its shape from bin to bin and wants little blending; far from it the bins are noisy and
  // change slowly, and want much. Empty: every bin alpha_blend. blend_width() gives bin b's.
  std::vector<int> alpha_blend_width;
  // Turning bins (format version 5): at exit angle alpha the direction density of bin j is the
  // bin's own turned about y by alpha_turn[j] * (alpha - centre of bin j), where the centre is
  // the middle of its alpha edges (turn_angle()): the forward peak turns with the exit point
  // (by 1.2-1.7 degrees per degree of alpha in forward-scattering media), and a density that
  // stands still across a bin blurs the turn into the bin's edges. Blended bins each turn by
  // their own rate. Empty: no bin turns (format versions before 5).
  std::vector<double> alpha_turn;
  static constexpr double kMaxTurn = 8;
  std::vector<BinStatus> status;          // [bins]

  // kVmf: `lobes` lobes per bin, [bins * lobes].
  int lobes = 0;
  std::vector<VmfLobe> vmf;
  // Hemispherical lobes (format version 3): in bin b each lobe is multiplied by the bin's mean
  // outward cosine (stf/hemisphere.h) and renormalised by lobe_norm, its integral, which
  // rebuild_lobe_norms() derives.
  bool hemispherical = false;
  // Lifted lobes (attribute `lifted`): at exit angle alpha a direction w of bin b is the
  // half-vector (v + n) / |v + n| of the exit normal n = (sin alpha, 0, cos alpha) (turned back
  // by the bin's turn, as w is) and a direction v of the lobe over the whole sphere; v is n
  // mirrored about w. The density is 4 (w . n) vMF(2 (w . n) w - n) above n's tangent plane and 0
  // below: it falls to zero at grazing as exits do, is normalised by construction (Lambertian at
  // kappa 0), and a draw is one vMF draw, an add and a normalisation, with no retries.
  bool lifted = false;
  // The family's name in model specs: "vmf", "hvmf", "lvmf" or "sh".
  const char* family() const { return kind == ModelKind::kSh ? "sh" : hemispherical ? "hvmf" : lifted ? "lvmf" : "vmf"; }
  std::vector<double> lobe_norm;  // [bins * lobes]
  BinSlice<const VmfLobe> lobes_of(int b) const { return bin_slice(vmf, b, lobes); }

  // kSh: real SH coefficients per bin, [bins * (band_limit + 1)^2], windowed and smoothed.
  // The density used is max(SH, 0) tabulated at the centres of an equal-area (z, phi) grid
  // of sh_nz x 2 sh_nz cells and renormalised: rebuild_sh_tables() derives it.
  int band_limit = 0;
  std::vector<double> sh;
  int sh_nz = 0;
  std::vector<float> sh_table;  // [bins * sh_nz * 2 sh_nz], density per steradian
  // Across alpha: when alpha_degree >= 0 the coefficients are a Chebyshev series in
  // cos(alpha) of that degree, [(alpha_degree + 1) * (band_limit + 1)^2], and `sh` holds its
  // values at the bin centres; only the series is packed.
  int alpha_degree = -1;
  std::vector<double> sh_chebyshev;

  int bins() const { return int(alpha_probability.size()); }
  double tilt(int b) const { return alpha_tilt.empty() ? 0.0 : alpha_tilt[std::size_t(b)]; }
  // The angle about y by which bin b's direction density is turned at exit angle alpha.
  double turn_angle(int b, double alpha) const {
    if (alpha_turn.empty()) return 0;
    const std::size_t i = std::size_t(b);
    return alpha_turn[i] * (alpha - 0.5 * (alpha_edges[i] + alpha_edges[i + 1]));
  }
  // The bins whose direction densities are blended at area fraction u of bin b, and their
  // weights (summing to 1); returns how many (at most 2 kMaxBlend + 1).
  int blend_weights(int b, double u, int* blend_bins, double* weights) const;
  int blend_width(int b) const { return alpha_blend_width.empty() ? alpha_blend : alpha_blend_width[std::size_t(b)]; }
  // Shares of all escapes: the uncollided delta, and the smooth (fitted) part in alpha bin b.
  double uncollided_probability() const { return (1 - once_fraction) * uncollided_fraction; }
  double smooth_probability(int b) const {
    return (1 - once_fraction) * (alpha_probability[b] - (b == 0 ? uncollided_fraction : 0.0));
  }
  // Of alpha bin 0's escapes, the share that is the uncollided delta.
  double uncollided_share_of_bin0() const {
    return alpha_probability.empty() || alpha_probability[0] <= 0 ? 0 : std::min(1.0, uncollided_fraction / alpha_probability[0]);
  }
  // Density p(w' | alpha bin) per steradian: the vMF mixture, or the tabulated clamped SH;
  // lifted lobes about the bin's middle normal.
  double direction_pdf(int bin, const Vec3& w) const;
  // The same at an exit point of normal `normal` (which lifted lobes are mapped about).
  double direction_pdf(int bin, const Vec3& w, const Vec3& normal) const;
  // The exit normal (sin, 0, cos) at the middle of bin b's alpha edges.
  Vec3 middle_normal(int b) const {
    const double middle = 0.5 * (alpha_edges[std::size_t(b)] + alpha_edges[std::size_t(b) + 1]);
    return {std::sin(middle), 0, std::cos(middle)};
  }
  void rebuild_sh_tables();
  void rebuild_lobe_norms();
  // A bin's mean outward cosine at w (1 for a model that is not hemispherical).
  double outward_factor(int bin, const Vec3& w) const;
  // Size of a pack holding just this model (stf/pack.h): parameters as float32.
  std::int64_t packed_bytes() const;
};

// The hats of a blended bin: at area fraction u of bin b (of `bins`), blended over `width`
// bins, the bins j with 1 - |b + u - j - 1/2| / width > 0 and those weights normalised; returns
// how many (at most 2 width + 1; width 0: bin b alone).
int blend_hats(int b, double u, int width, int bins, int* blend_bins, double* weights);

// The limits every reader and writer of models holds to (model files, packs, `stf pack`):
// what the pack format and the sampler's tables hold.
inline constexpr int kMaxModelBins = 100000, kMaxLobes = 64, kMaxBandLimit = 64, kMaxShNz = 256;
inline constexpr int kMaxAlphaDegree = 64;
inline constexpr double kMaxShTableCells = 0x1p27;  // bins * sh_nz * 2 sh_nz floats: 512 MiB
inline constexpr double kMaxModelTau = 1e7;         // the largest table stf precomputes
// The narrowest alpha bin (radians): a bin's area 2 pi (cos a0 - cos a1) stays a number > 0 even
// at alpha = pi (100000 equal bins are 3e-5 wide).
inline constexpr double kMinAlphaBinWidth = 1e-6;
// The once-scattered part is at most tau e^-tau of the paths, nothing in float64 beyond tau
// ~745, and its draw's bound is built for tau up to ~1000: a model that claims one above this
// tau cannot be drawn from.
inline constexpr double kMaxOnceTau = 1000;

// Why a model of these sizes exceeds the limits (sh: band limit `size`, table rows `nz` and
// alpha degree `degree`; vMF: `size` lobes), or "" when it does not.
std::string model_size_error(bool sh, double bins, double size, double nz, double degree);

// Why a part of `m` cannot be drawn from in a bounded time (alpha probabilities all 0, a
// once-scattered part above kMaxOnceTau), or "". (A hemispherical lobe of almost no outward
// mass is dropped by rebuild_lobe_norms(), so its draw needs no check.)
std::string draw_error(const StfModel& m);

// Why `m` is not a usable model (values out of range or not finite, inconsistent sizes, parts
// that cannot be drawn from), or empty when it is. Loaders check once, so sampling code can
// trust what it is given.
std::string model_error(const StfModel& m);

// Cell of the equal-area (z, phi) grid with nz rows in z and 2 nz columns in phi.
int equal_area_cell(int nz, const Vec3& w);
// The direction at (in_cell, v) in [0, 1)^2 of such a cell: uniform in z and phi is uniform in
// area, so uniforms give a uniform point of the cell.
Vec3 equal_area_direction(int nz, int cell, double in_cell, double v);

}  // namespace stf
