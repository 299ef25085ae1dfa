// Fits a mixture of von Mises-Fisher lobes to one alpha bin's direction histogram by the
// binned Poisson likelihood (Ceres, Levenberg-Marquardt on deviance residuals).
#pragma once

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include "grid.h"
#include "stf/vmf.h"

namespace stf::fit {

class QuadratureLevels;

// A bin's mean outward cosine (stf/hemisphere.h) at every point of each quadrature level: the
// factor that makes vMF lobes hemispherical. Empty vectors: plain lobes.
using OutwardFactors = std::array<std::vector<double>, 3>;

// An alpha bin whose direction density turns about y with the exit angle (StfModel::alpha_turn):
// its counts are the density averaged over the bin's exit points (its edges a0, a1 and tilt),
// each turned by rate * (alpha - (a0 + a1) / 2).
struct BinTurn {
  double rate = 0, a0 = 0, a1 = 0, tilt = 0;
};

// A neighbouring alpha bin's escapes fitted together with a bin's own: they are expected to
// follow the bin's lobes turned by `angle` about y (the axis the exit point turns about as
// alpha grows), times the neighbour's own outward factor, and their log-likelihood counts
// `weight` times.
struct PooledBin {
  const std::vector<double>* counts = nullptr;
  const OutwardFactors* outward = nullptr;  // null: plain lobes
  double angle = 0, weight = 0;
  int offset = 0;  // its bin minus the fitted one: how far sloped lobes are continued
  const BinTurn* turn = nullptr;  // how the neighbour's own density turns across it, or null
};

struct VmfFitOptions {
  const OutwardFactors* outward = nullptr;  // hemispherical lobes of this bin, or null
  const BinTurn* turn = nullptr;            // the bin's density turns across it, or null
  std::vector<PooledBin> pooled;            // neighbours fitted jointly (none: the bin alone)
  // Whether the neighbours see the lobes continued linearly in alpha (each lobe's logit, log
  // kappa and turn sloped by parameters of their own, fitted with the lobes) rather than as
  // they are: a local-linear fit, whose neighbours tell the bin's lobes nothing of their change
  // of shape, only of what the bin shares with them.
  bool sloped = false;
  int max_iterations = 100;
  // Stop once the deviance changes by less than this share of itself between iterations:
  // 1e-5 is ~0.05 at the deviances of a bin's few thousand cells, far below one unit, the
  // scale of statistically meaningful differences. (Larger steps toward it are no guide: a fit
  // from split lobes can move by less than 1e-4 per iteration with thousands of units to go.)
  double function_tolerance = 1e-5;
  // Bounds on kappa (the weights' logits are bounded to [-40, 40]). A parameter at its bound
  // stays there while the others converge (PoissonDeviance).
  double min_kappa = 1e-6, max_kappa = 1e8;
};

struct VmfFitResult {
  std::vector<VmfLobe> lobes;  // weights sum to 1
  double deviance = 0;         // Poisson deviance of the fit: 2 sum n log(n / mu) - (n - mu), pooled bins weighted in
  int iterations = 0;
};

// Cell quadratures of one grid at levels 0 .. kMaxLevel, built once per table.
class QuadratureLevels {
 public:
  static constexpr int kMaxLevel = 2;
  explicit QuadratureLevels(const DirectionGrid& grid);
  const CellQuadrature& at(int level) const { return levels_[level]; }
  // The coarsest level accurate enough for lobes up to `kappa` against `counts` escapes: the
  // widened point rule errs by O((kappa a / 12)^2) (a = sub-cell solid angle), kept below
  // the Poisson noise by kappa a / 12 <= 0.25 counts^(-1/4). At most kMaxLevel; beyond it
  // the widening alone carries near-delta lobes.
  const CellQuadrature& for_kappa(double kappa, double counts = 1e8) const { return at(level_for_kappa(kappa, counts)); }
  int level_for_kappa(double kappa, double counts = 1e8) const;
  // The cell holding +z, where the uncollided delta lands.
  std::int64_t pole_cell() const { return pole_cell_; }
  // Each cell's centre, and the largest angle from a cell's centre to its points at a level:
  // a lobe can skip a whole cell when its nearest possible point is beyond its reach.
  const std::vector<Vec3>& centres() const { return centres_; }
  double spread(int level) const { return spread_[std::size_t(level)]; }
  // The cells [first, last) outside which no centre lies within `reach` radians of `mean`, by
  // the centres' z alone: on a grid numbered ring by ring (HEALPix) a narrow lobe's cells are
  // a short run of indices, and a loop over them visits its cells in the same order as one
  // over all cells.
  std::pair<std::size_t, std::size_t> cell_range(const Vec3& mean, double reach) const;
  // For a level below kMaxLevel: the point of that level whose sub-cell holds each point of
  // kMaxLevel (the nearest of its cell's).
  const std::vector<std::uint32_t>& finest_parent(int level) const { return finest_parent_[std::size_t(level)]; }

 private:
  std::vector<CellQuadrature> levels_;
  std::array<std::vector<std::uint32_t>, kMaxLevel> finest_parent_;
  std::vector<Vec3> centres_;
  // The smallest centre z of cells 0 .. c and the largest of cells c .. end: both never rise
  // with c, so they bound a z band's cells by binary search whatever the numbering.
  std::vector<double> lowest_z_up_to_, highest_z_from_;
  std::vector<double> spread_;
  double cell_solid_angle_;  // the largest cell's
  std::int64_t pole_cell_ = 0;
};

// Per-cell probabilities of a vMF mixture, each lobe at the quadrature level the fit used for
// it against `counts` escapes; with `outward`, of hemispherical lobes.
std::vector<double> vmf_cell_probabilities(const std::vector<VmfLobe>& lobes, const QuadratureLevels& levels,
                                           double counts = 1e8, const OutwardFactors* outward = nullptr);

// The same for a bin whose density turns across it: the turned density averaged over the bin's
// exit points, as the fit sees a turning bin's counts (VmfFitOptions::turn).
std::vector<double> vmf_bin_probabilities(const std::vector<VmfLobe>& lobes, const QuadratureLevels& levels,
                                          double counts, const OutwardFactors* outward, const BinTurn& turn);

// The outward factors of the alpha bin [a0, a1] at the points of every level.
OutwardFactors outward_factors(const QuadratureLevels& levels, double a0, double a1);
// The same, but at the levels below kMaxLevel each point carries the factor's mean over the
// finest points of its sub-cell: what `stf eval`, plots and tolerance certificates integrate
// models with. The factor falls to 0 across the bin's tangent planes, and its value at a point
// gives a cell the plane cuts none of its outward part when the point lies below, where the
// sampler draws directions and a table has escapes. (The fit keeps the point values: averaged
// there too, the tau 1 g 0.9 models of 1e5 paths came out farther, docs/fit.md.)
OutwardFactors outward_cell_means(const QuadratureLevels& levels, double a0, double a1);

// `counts` per cell of the grid; their total must be > 0. Each lobe is integrated at the
// quadrature level its kappa needs (QuadratureLevels::for_kappa).
VmfFitResult fit_vmf(const std::vector<double>& counts, const QuadratureLevels& levels, int lobes,
                     const VmfFitOptions& options = {});

// K start lobes from a fit with fewer (or as many): its heaviest lobes split in two.
std::vector<VmfLobe> grow_lobes(std::vector<VmfLobe> lobes, int K);

// The same, from given start lobes (e.g. a fit of the same size to fewer escapes).
VmfFitResult fit_vmf_from(const std::vector<double>& counts, const QuadratureLevels& levels,
                          const std::vector<VmfLobe>& start, const VmfFitOptions& options = {});

// The deterministic starting point: spherical k-means on cell centres weighted by counts
// (seeded at the fullest cell, then farthest-first), weights from the cluster masses, kappa
// from each cluster's mean resultant length (Banerjee et al. 2005).
std::vector<VmfLobe> initial_lobes(const std::vector<double>& counts, const CellQuadrature& q,
                                   int lobes);

}  // namespace stf::fit
