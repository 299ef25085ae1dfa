// Where fitted direction densities meet a grid's cells: the grid's quadrature levels, the
// outward factors of hemispherical lobes, the batched integrator of vMF lobes over the cells
// with the one rule for bins whose density turns across them, the integral of any density
// (SH models) and the Poisson deviance of counts against cell probabilities. The fit's cost
// functions (lobe_deviance.h), its held-out scores, `stf eval` and the tolerance certificates
// integrate lobes here.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <utility>
#include <vector>

#include "stf/core/grid.h"
#include "stf/hemisphere.h"
#include "stf/vmf.h"

namespace stf::fit {

// A bin's mean outward cosine (stf/hemisphere.h) at every point of each quadrature level: the
// factor that makes vMF lobes hemispherical. Empty vectors: plain lobes.
using OutwardFactors = std::array<std::vector<double>, 3>;

// An alpha bin whose direction density turns about y with the exit angle (StfModel::alpha_turn):
// its counts are the density averaged over the bin's exit points (its edges a0, a1 and tilt),
// each turned by rate * (alpha - (a0 + a1) / 2).
struct BinTurn {
  double rate = 0, a0 = 0, a1 = 0, tilt = 0;
  // Lifted lobes (StfModel::lifted): at each exit point the lobe is mapped to the outward
  // hemisphere of that point's normal, so the counts average it over the exit points even where
  // the rate is 0.
  bool lifted = false;
};

// The quadrature levels SH cell probabilities are taken at. The fit's choice of smoothing
// scores every candidate on the held-out half, so it integrates at level 1 (4 points a cell), a
// quarter of level 2's cost; the fit's diagnostics and every measure (stf/measure/) integrate
// the finished model's density at level 2 (16 points a cell). vMF lobes choose their own level
// by their width (lobe_cell_probabilities), in the fit and in the measures alike.
inline constexpr int kShScoreLevel = 1, kShMeasureLevel = 2;

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
  int level_for_kappa(double kappa, double counts = 1e8) const;
  // Each cell's centre, and the largest angle from a cell's centre to its points at a level:
  // a lobe can skip a whole cell when its nearest possible point is beyond its reach.
  const std::vector<Vec3>& centres() const { return centres_; }
  double spread(int level) const { return spread_[std::size_t(level)]; }
  // The largest sub-cell solid angle at a level (the widening's scale).
  double max_sub_cell(int level) const { return max_sub_cell_[std::size_t(level)]; }
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
  std::vector<double> max_sub_cell_;
  double cell_solid_angle_;  // the largest cell's
};

// Whether cells far from every lobe keep their small mass: where ratios of cell probabilities
// are taken (KL, deviances, chi^2), not where they are mixed with a floor far above it (held-out
// scores). kKeep integrates every point however far below a lobe's peak; kCut skips points beyond
// 40 e-folds, which changes no sum a double holds but leaves far cells at exactly 0.
enum class Tails { kKeep, kCut };

// Per-cell probabilities of a vMF mixture (weights summing to 1) over every cell of the grid,
// each lobe integrated by LobeIntegrator as for `counts` escapes (its quadrature level and
// widening); with `outward`, of hemispherical lobes; with `turn`, averaged over the exit points
// of a bin whose density turns across it, as the fit sees a turning bin's counts.
std::vector<double> lobe_cell_probabilities(const std::vector<VmfLobe>& lobes, const QuadratureLevels& levels,
                                            double counts = 1e8, const OutwardFactors* outward = nullptr,
                                            const BinTurn* turn = nullptr, Tails tails = Tails::kKeep);

// Per-cell probabilities of a density per steradian (an SH model's) by the points of quadrature
// `q`, normalised to sum to 1 (all zero if the density vanishes everywhere).
std::vector<double> density_cell_probabilities(const std::function<double(const Vec3&)>& density,
                                               const CellQuadrature& q);

// Poisson deviance 2 sum [n log(n / mu) - (n - mu)] of counts against mu = total * p: twice
// the log-likelihood ratio of the saturated model; smaller is a better fit.
double poisson_deviance(const std::vector<double>& counts, const std::vector<double>& p);

// The outward factors of the alpha bin [a0, a1] at the points of every level.
OutwardFactors outward_factors(const QuadratureLevels& levels, double a0, double a1);
// The same, but at the levels below kMaxLevel each point carries the factor's mean over the
// finest points of its sub-cell: what `stf eval`, plots and tolerance certificates integrate
// models with. The factor falls to 0 across the bin's tangent planes, and its value at a point
// gives a cell the plane cuts none of its outward part when the point lies below, where the
// sampler draws directions and a table has escapes. (The fit keeps the point values: averaged
// there too, its models came out farther from the references; docs/studies/
// 2026-12-fit-measurements.md, "What is left at tau 1 g 0.9".)
OutwardFactors outward_cell_means(const QuadratureLevels& levels, double a0, double a1);

// vMF lobes integrated over the cells of one histogram, batched: each lobe at the quadrature
// level its kappa needs against the histogram's escapes (widened to its sub-cells where that
// matters against the Poisson noise, points beyond 40 e-folds skipped), times the bin's outward
// factor for hemispherical lobes, and in a bin that turns (BinTurn) as the mean of turned
// copies. Rows are the cells with counts; a lobe's mass outside them goes to its total only.
class LobeIntegrator {
 public:
  // `counts` per cell of the grid; `outward` (hemispherical lobes) and `turn` may be null. Lobes
  // are integrated as accurately as `accurate_for` escapes need (levels, widening; negative: the
  // counts' sum), their far points kept or cut by `tails`.
  LobeIntegrator(const QuadratureLevels& levels, const std::vector<double>& counts, const OutwardFactors* outward,
                 const BinTurn* turn, double accurate_for = -1, Tails tails = Tails::kCut);

  // Where one lobe's integrals go: its masses on the rows (and, with derivatives, their
  // derivatives by log kappa and by the mean), and its totals over the sphere.
  struct LobeIntegrals {
    double *mass, *d_theta, *d_mean;
    double *total, *total_theta, *total_mean;
    // When given, the rows the lobe reaches are listed once each (`marked` flags them).
    std::vector<int>* touched = nullptr;
    char* marked = nullptr;
  };

  // One copy's integrals, zero outside the rows it reached (`touched`, flagged in `marked`), which
  // are zeroed again after they are folded in: allocated once per evaluation, not once per lobe.
  struct CopyScratch {
    std::vector<double> m, dt, dm;
    std::vector<char> marked;
    std::vector<int> touched;
    CopyScratch(int rows, bool derivatives, bool needed)
        : m(needed ? std::size_t(rows) : 0, 0.0), dt(needed && derivatives ? std::size_t(rows) : 0, 0.0),
          dm(needed && derivatives ? 3 * std::size_t(rows) : 0, 0.0), marked(needed ? std::size_t(rows) : 0, 0) {}
  };
  CopyScratch make_scratch(bool derivatives) const { return CopyScratch(rows(), derivatives, !nodes_.empty()); }

  int rows() const { return int(count_.size()); }
  const std::vector<double>& row_counts() const { return count_; }
  double escapes() const { return total_; }

  // One lobe of the bin. In a turning bin (VmfFitOptions::turn) the lobe is the mean of its
  // turned copies, each normalised over the sphere, so its masses are normalised already (totals
  // 1, no pull). The copy at turn t has its mean turned by t and the outward factor of the bin's
  // edges moved by t, and d mass / d mean = R(t)^T d mass / d (R(t) mean). A lobe broad against
  // the turn across the bin (one copy), and every lobe of a bin that stands still, is integrated
  // as it stands. Only the rows a copy reaches are folded in.
  void integrate_bin_lobe(const Vec3& mean, double kappa, const LobeIntegrals& out, CopyScratch& scratch) const;

  // The probabilities of the rows' cells under `lobes` (the deviance's model, without the
  // residuals).
  std::vector<double> probabilities(const std::vector<VmfLobe>& lobes) const;

 private:
  // The outward factor at quadrature point i (at x): from a bin's table, from a turned bin's
  // edges, or 1 for plain lobes.
  struct PointFactor {
    const OutwardFactors* table = nullptr;
    const OutwardBin* turned = nullptr;
    // Lifted lobes: the exit normal n that a point x is mapped about, to v = 2 (x . n) x - n with
    // its sub-cell's solid angle times 4 (x . n) (the reflection's Jacobian); none below n's
    // tangent plane.
    const Vec3* lift = nullptr;
    const double* at_level = nullptr;
    void for_level(int level) { at_level = table ? (*table)[std::size_t(level)].data() : nullptr; }
    double operator()(std::size_t i, const Vec3& x) const { return at_level ? at_level[i] : turned ? (*turned)(x) : 1.0; }
  };

  // Points of one lobe whose exponentials are taken together (exp_in_place, several to an
  // instruction): each point's exponent and what multiplies the exponential, in the order the
  // points were met, so that each row's sums are added in the same order as point by point.
  struct PointBatch {
    static constexpr int kSize = 64;
    int n = 0;
    double exponent[kSize], scale[kSize], theta[kSize], theta_scale[kSize], mean_scale[kSize], factor[kSize];
    int row[kSize];
    const Vec3* x[kSize];
    Vec3 mapped[kSize];  // lifted lobes' points, where x points
  };

  // Adds the batch's points to `out` and empties it. The totals are summed here first: added to
  // `out` point by point they would be a chain of stores the compiler cannot keep in registers
  // (`out`'s arrays might overlap them).
  static void flush(PointBatch& b, bool derivatives, const LobeIntegrals& out);
  // Adds one lobe's cell masses, totals and their derivatives to `out`, each point times its
  // outward factor.
  void integrate_lobe(const Vec3& mean, double kappa, PointFactor factor, const LobeIntegrals& out) const;
  // Calls add(cell, x, a, f) for each point of `level` in the cells within `reach` of `mean`: x
  // the point (mapped about factor.lift for lifted lobes, into `batch`), a its sub-cell's solid
  // angle (times the map's Jacobian), f its outward factor.
  template <typename Add>
  void for_each_point(int level, const Vec3& mean, double reach, const PointFactor& factor, PointBatch& batch,
                      Add& add) const;

  // Copies of a lobe at n turns across the bin: the midpoints of n equal shares of the exit
  // points (the bin's tilted density in area), turned by the rate times their angle from the
  // bin's middle, for n = 1 .. kMaxTurnNodes.
  struct Node {
    double angle, weight;
    OutwardBin outward;
    Vec3 normal;  // the exit normal at the node's exit angle (lifted lobes are mapped about it)
  };
  void turn_nodes(const BinTurn& turn);
  // Copies enough that neighbours are a lobe width (1 / sqrt(kappa)) apart or closer.
  // A lifted lobe is as narrow in the directions as a plain one of 4 kappa (the map halves
  // angles), and its support turns with the exit normal: at least one copy every
  // kLiftedNodeSpacing of exit angle, whatever its width.
  int nodes_needed(double kappa) const {
    return std::clamp(int(std::ceil(kTurnNodesPerWidth * span_ * std::sqrt(lifted_ ? 4 * kappa : kappa))), least_nodes_,
                      kMaxTurnNodes);
  }
  static constexpr double kLiftedNodeSpacing = 0.02;
  int least_nodes_ = 1;
  static constexpr int kMaxTurnNodes = 16;
  // Copies one lobe width apart: closer copies slow the fit and move no model (docs/studies/
  // 2026-12-fit-measurements.md, "Densities that turn with the exit point").
  static constexpr double kTurnNodesPerWidth = 1;

  const QuadratureLevels& levels_;
  const OutwardFactors* outward_;
  bool lifted_ = false;
  Vec3 middle_normal_;  // lifted lobes integrated as one copy are mapped about the bin's middle
  std::vector<std::vector<Node>> nodes_;  // [n - 1]: n copies; empty: the bin does not turn
  double span_ = 0;                       // the turn across the bin
  std::vector<int> row_of_cell_;
  std::vector<double> count_;
  double total_ = 0;         // the counts' sum
  double accurate_for_ = 0;  // the escapes the integrals are as accurate as
  double widen_above_ = 0;   // kappa a / 12 beyond which lobes are widened
  double cut_efolds_ = 40;   // points farther below a lobe's peak are skipped
};

}  // namespace stf::fit
