// The stages fit_table() (fit_table.cpp) runs, shared by the files that hold them:
//  - fit_escapes.cpp: a table's escapes per alpha bin (folded over the mirror, without the
//    singular parts), the singular parts' and the rest's probabilities, absorption;
//  - fit_bins.cpp: one pass of fitting every bin of the table or of one half, pooled or not;
//  - fit_heldout.cpp: held-out scores, and with them the model size;
//  - fit_neighbours.cpp: the pools, and what each bin takes from its neighbours;
//  - fit_blend.cpp: the blend widths, from held-out scores of turned neighbours;
//  - fit_alpha.cpp: the alpha marginal, the tilts and the turns;
//  - fit_model.cpp: the model of the final fits and its diagnostics.
// Internal to fit/: the names live in stf::fit::stages.
#pragma once

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "alpha_marginal.h"
#include "stf/fit/alpha_tilt.h"
#include "stf/fit/cell_integral.h"
#include "stf/fit/fit_settings.h"
#include "stf/core/table.h"
#include "stf/core/grid.h"
#include "mirror.h"
#include "stf/fit/parallel.h"
#include "sh_fit.h"
#include "stf/once_scattered.h"
#include "stf/sh.h"
#include "stf/fit/vmf_fit.h"

namespace stf::fit {

// A triangle in the distance d (bins): the nearest neighbours of width 1 count 1/2.
inline constexpr double pool_weight(int width, int d) { return 1 - d / double(width + 1); }

// The bins' headings (mean exit directions' angles about y, per alpha bin) smoothed across
// alpha for sloped pools: a sparse bin's heading scatters by degrees (a few hundred escapes
// spread over tens of degrees), the true one turns smoothly with the exit point. Each becomes
// the value at its bin of a local quadratic in the bin index over the bins within
// kConfig.heading_window, least squares weighted by their escapes and a triangle in the distance;
// headings are unwrapped first, as they may cross +-pi. Bins whose window holds fewer than three
// bins with escapes keep their own. `slopes`, when given, receives each local quadratic's slope at
// its bin, per bin (0 where a bin keeps its own heading).
std::vector<double> smooth_headings(std::vector<double> headings, const std::vector<double>& escapes,
                                    std::vector<double>* slopes = nullptr);

// The rate at which each bin's direction density turns about y with the exit angle
// (StfModel::alpha_turn), in radians per radian of alpha: the slope at the bin of its smoothed
// heading (smooth_headings of the bins' headings and escapes after two or more collisions),
// clamped to +-kConfig.max_fitted_turn; 0 where the slope is not known.
std::vector<double> alpha_turns(const std::vector<double>& headings, const std::vector<double>& escapes,
                                const std::vector<double>& alpha_edges);

}  // namespace stf::fit

namespace stf::fit::stages {

// Escaped weight per cell of alpha bin b: the full table (half < 0) or one half-table.
std::vector<double> bin_counts(const Table& t, int half, int b);

double sum(const std::vector<double>& v);

// Bin b's escapes after two or more collisions, both halves: what a bin's lobes are integrated
// against (the quadrature level of each lobe).
double both_halves(const Table& t, int b);

// The angle about y from the exit point's z axis to where escapes with these cell counts head
// on average (their mean direction's azimuth in the x-z plane of the exit point's frame).
double heading(const Table& t, const std::vector<double>& counts);

// The escapes a fit sees per alpha bin (bin_counts), folded over the mirror symmetry of the
// exit distribution when `image` (mirror_cells) is not empty. Folding bin by bin as the counts
// are read keeps no second copy of the table; it keeps each bin's total.
struct Escapes {
  Escapes(const Table& t, std::vector<std::int64_t> mirror) : table(t), image(std::move(mirror)) {
    for (int b = 0; b < t.alpha_bins; ++b) total.push_back(sum(bin_counts(t, -1, b)));
  }
  const Table& table;
  std::vector<std::int64_t> image;
  std::vector<double> total;  // per bin, both halves
  // How each bin's density turns across it in fits of the whole table (empty: the bins stand
  // still). The half-table fits that choose sizes, pools and blends stand still: turning them
  // too chose models farther from the references (docs/studies/2026-12-fit-measurements.md,
  // "Densities that turn with the exit point").
  std::vector<BinTurn> turns;
  // Lifted lobes (FitSettings::lifted) are mapped about each exit point's normal in every fit:
  // each bin's BinTurn where its density stands still.
  std::vector<BinTurn> still;
  std::vector<double> counts(int half, int b) const {
    std::vector<double> c = bin_counts(table, half, b);
    if (!image.empty()) fold_over_mirror(c, image);
    return c;
  }
  const BinTurn* turn_of(int half, int b) const {
    return half < 0 && !turns.empty() ? &turns[std::size_t(b)] : still.empty() ? nullptr : &still[std::size_t(b)];
  }
  void set_lifted();
  // The rates from the headings of the whole table's escapes (alpha_turns), the exit points
  // spread by `tilts` (none: uniform in area).
  void set_turns(const std::vector<double>& tilts) {
    std::vector<double> headings;
    for (int b = 0; b < table.alpha_bins; ++b) headings.push_back(heading(table, counts(-1, b)));
    const std::vector<double> rate = alpha_turns(headings, total, table.alpha_edges);
    for (int b = 0; b < table.alpha_bins; ++b)
      turns.push_back({rate[std::size_t(b)], table.alpha_edges[std::size_t(b)], table.alpha_edges[std::size_t(b) + 1],
                       tilts.empty() ? 0.0 : tilts[std::size_t(b)], !still.empty()});
  }
};

double uncollided_escapes(const Table& t);

// Probabilities of the exact parts, per path launched. With the once-scattered escapes tallied
// apart (tables since format 1 with /escape/once_half) both singular parts are known exactly:
// e^{-tau} and the one-collision quadrature; the walk's counts of them are not needed, and only
// the escapes after two or more collisions carry Monte Carlo noise. Older tables give the
// tallied uncollided share and no once-scattered part.
struct SingularParts {
  double uncollided = 0, once = 0;
};

bool singular_parts_exact(const Table& t);

// The parts' probabilities from the medium alone: e^{-tau} and the one-collision quadrature.
SingularParts medium_singular_parts(const Table& t);

SingularParts singular_parts(const Table& t);

// Probabilities per path of the walk's other outcomes: the escapes after two or more collisions
// (as the factor that turns their tallied count into paths), absorption and truncation. They
// sum to 1 with the exact singular parts. Without exact singular parts, the plain shares.
struct RestProbabilities {
  double fitted_scale = 1, absorbed = 0, truncated = 0;
};

// Absorption estimated with three control variates of known mean (docs/design.md, "Singular
// parts"): the uncollided and the once-scattered indicators (means p0, p1) and
// D = (1 - albedo) c - A over a path of c decided collisions, A its absorption (mean 0: every
// decided collision absorbs with probability 1 - albedo, whatever came before). Their
// covariances with each other and with A follow from the table's totals, the collisions of the
// absorbed paths among them; the regression on all three is the linear estimator of least
// variance, for many paths at most that of A's plain share and of (1 - albedo) c alone. Its
// coefficients come from the same totals as the means they multiply, which biases it by O(1/n),
// far below its standard deviation at the table sizes stf fits.
// Returns -1 where the table does not tally the absorbed paths' collisions or D is constant
// (albedo 0 or 1).
double absorption_by_regression(const Table& t, const SingularParts& exact);

// The paths that neither escaped uncollided nor after one collision split among the other
// outcomes independently of how many they were, so each outcome's share of them times the exact
// 1 - p0 - p1 estimates its probability with the singular parts' noise taken out.
// Absorption then comes from the regression where the table allows it, and the escapes after two
// or more collisions take what is left: with rare absorption (albedo near 1) the collision count
// knows it far better than the absorbed paths do. Where no path is left after the exact parts
// (tiny tau or tables), nothing tallied can carry the rest: it goes to absorption, which is what
// a renderer makes of a lost path.
RestProbabilities rest_probabilities(const Table& t, const SingularParts& exact);

// Bins whose status is kBorrowed take the parameters of the nearest fitted bin (the lower
// one on a tie); with no fitted bin at all they become kEmpty with `uniform`.
template <typename P>
void fill_borrowed(std::vector<BinStatus>& status, std::vector<P>& params, const P& uniform) {
  const int bins = int(status.size());
  for (int b = 0; b < bins; ++b) {
    if (status[b] != BinStatus::kBorrowed) continue;
    int source = -1;
    for (int d = 1; d < bins && source < 0; ++d) {
      if (b - d >= 0 && status[b - d] == BinStatus::kFitted) source = b - d;
      else if (b + d < bins && status[b + d] == BinStatus::kFitted) source = b + d;
    }
    if (source < 0) status[b] = BinStatus::kEmpty;
    params[b] = source < 0 ? uniform : params[source];
  }
}

// Everything one pass of fitting (on the full table or one half) produces.
struct BinFits {
  const Table* table = nullptr;
  ModelKind kind = ModelKind::kVmf;
  int size = 0;  // lobes or band limit
  bool hemispherical = false, lifted = false;
  std::vector<BinTurn> turns;  // how the fitted densities turn across their bins (empty: they stand still)
  std::vector<BinStatus> status;
  std::vector<std::vector<VmfLobe>> lobes;  // vmf
  std::vector<std::vector<double>> sh;      // sh: raw projections, not yet smoothed
};

// Whether bin b is sparse enough for its neighbours' escapes to pay (FitSettings::
// pool_neighbours): pooling trades noise for bias, and where a bin's own escapes are many it
// moves no model while its fits take several times as long.
bool worth_pooling(const Escapes& e, int b);

// Whether a half-table holds too few of bin b's escapes for `size` lobes (kConfig.escapes_per_lobe each):
// the bin's own escapes, not the family, limit its model whatever its size, so its neighbours'
// are worth reaching farther for (wide_pooling).
bool capped_by_escapes(const Escapes& e, int b, int size);

// Whether bin b is noisy enough for a sloped pool (PoolTry) to be worth its cost: fewer than
// kConfig.sloped_pool_escapes_per_lobe escapes per lobe of the chosen size.
bool noisy(const Escapes& e, int b, int size);

// Which bins a pass of fit_bins pools, and how (PoolTry): bin b with the bins within its width
// on either side (0: alone). Bins of width 0 copy their lobes from `others` when given (fitted
// alone or chosen before, at the same size on the same half). A `trial` pass only ranks pools
// for wide_pooling: its pooled fits stop after kConfig.pool_try_iterations.
struct Pooling {
  std::vector<PoolTry> bin;
  const BinFits* others = nullptr;
  bool trial = false;
  bool any() const { return std::any_of(bin.begin(), bin.end(), [](const PoolTry& p) { return p.width > 0; }); }
  PoolTry of(int b) const { return bin.empty() ? PoolTry{} : bin[std::size_t(b)]; }
};

// One pass of fit_bins: the half-table (0 or 1) or the whole table (-1), the size, and where
// the lobes start and reach. `start`: fits (on a half-table, of this size or smaller) to start
// the lobes from, or null; missing lobes come from splitting the heaviest ones (grow_lobes).
// `pool` (vmf): a bin of width w > 0 has its lobes fitted to its own escapes and, with weights
// pool_weight(w, d), to those of the bins d <= w away, expected where the bin's go turned about
// y by the difference of their headings (the forward peak turns with the exit point:
// docs/fit.md, "The pipeline"), and continued linearly in alpha where the pool is sloped; it
// gets a lobe per kConfig.escapes_per_lobe of all the escapes so weighted.
struct Pass {
  int half = -1;
  int size = 0;                            // lobes or band limit
  const ShProjector* projector = nullptr;  // SH
  const BinFits* start = nullptr;
  const Pooling* pool = nullptr;
};

// Fits every bin of `s.kind` for the pass; bins with too few escapes borrow a neighbour's.
BinFits fit_bins(const Escapes& e, const Pass& pass, const QuadratureLevels& levels, const FitSettings& s);

// Cell probabilities of vMF lobes of `fits`' kind in a bin with the edges and turn of `bin`
// (rate 0: it stands still): hemispherical lobes times the edges' outward factor.
std::vector<double> lobe_cells(const BinFits& fits, const std::vector<VmfLobe>& lobes, const QuadratureLevels& levels,
                               double escapes, const BinTurn& bin, Tails tails);

// Cell probabilities of bin b under fitted parameters (vMF, or clamped smoothed SH).
std::vector<double> bin_probabilities(const BinFits& fits, int b, const ShSmoothing& t, const QuadratureLevels& levels,
                                      const std::vector<double>& sh_basis, Tails tails);

// Held-out negative log-likelihood of half `half` under probabilities per bin, with p mixed
// 1e-6 with the uniform density so that a cell the model calls empty costs a finite amount.
struct HeldOut {
  double nll = 0;
  std::vector<double> bin_nll;             // per bin; they sum to nll
  std::vector<std::vector<double>> log_p;  // per bin, per cell
};

HeldOut score(const Escapes& e, int half, const std::vector<std::vector<double>>& p);

// Standard error of the held-out NLL difference between two models: the paths are independent,
// so its variance is the sum over bins of the multinomial variance of sum n_c d_c.
double difference_error(const Escapes& e, int half, const HeldOut& a, const HeldOut& b);

// SH smoothings tried on held-out data: with and without the Lanczos window, times heat
// kernels from none to strong. A plain projection (no window, t = 0) is one of them, so a
// fit is never forced to smooth more than the data want.
std::vector<ShSmoothing> sh_smoothings();

// A size tried on the held-out half: the fits on half 0 and their score on half 1, and for SH
// the smoothing with the lowest held-out NLL.
struct SizeTrial {
  HeldOut score;
  ShSmoothing smoothing;
  BinFits fits;
};

// Fits the pass on half 0 (`pass.half` is ignored) and scores it on half 1. vMF lobes start
// from `pass.start` when given (the next smaller candidate's fits).
SizeTrial heldout_for_size(const Escapes& e, const FitSettings& s, Pass pass, const DirectionGrid& grid,
                           const QuadratureLevels& levels);

// The model size: given, or the candidate with the lowest held-out NLL, an unbiased estimate of
// the model's cross-entropy with the truth. (A rule that prefers smaller models within noise
// would err twice toward too few parameters: the candidates are fitted to half the escapes
// the final model is.) Candidates (auto_candidates) go up in size until two in a row fail to
// lower the lowest held-out NLL so far: the NLL of neighbouring sizes can sit on a plateau
// within a nat while larger sizes gain tens, and the search must not end there. vMF lobes of
// each size start from the smaller size's. SH models also choose their smoothing here.
struct SizeChoice {
  std::vector<BinFits> half_fits;  // the candidates' fits on half 0, in the order tried
  std::size_t best = 0;            // the lowest held-out NLL among them (auto: auto_candidates' index)
  int size = 0;                    // chosen (pools may change it)
  ShSmoothing smoothing;
  BinFits fits;   // the chosen fits on half 0: where the final fit's lobes start
  HeldOut score;  // their held-out score on half 1
};

// Fills `r`'s candidates, held-out NLLs and their errors. With neither auto nor SH: the given
// size, nothing fitted.
SizeChoice choose_size(const Escapes& e, const FitSettings& s, const DirectionGrid& grid, const QuadratureLevels& levels,
                       FitReport& r);

// Neighbour pooling adds no parameter but a bias (the neighbours' escapes are not quite the
// bin's turned), so it can only pay where noise, not the family, limits the model: where the
// held-out NLL stopped falling before the largest size (`best`, an index into the candidates
// tried), and in bins with few escapes (worth_pooling). Then the chosen size and the next are
// fitted pooled on half 0 (the other bins as fitted alone); a pooled fit replaces the choice
// (its size, half-0 fits and score) when its held-out NLL is lower (the rule of the sizes).
// Returns each bin's pool: the nearest neighbours in the bins worth pooling when pooling won,
// else none.
std::vector<PoolTry> choose_pooling(const Escapes& e, const FitSettings& s, const DirectionGrid& grid,
                                    const QuadratureLevels& levels, SizeChoice& choice, FitReport& r);

// What a pass of pools gains in each bin it tries: the held-out NLL the pooled fits save against
// the choice so far, in the bin and, weighted kConfig.neighbour_gain_weight, in its two
// neighbours where they tried the same pool.
std::vector<double> pooled_gain(const Pooling& pool, const HeldOut& before, const HeldOut& pooled);

// Wider pools (kConfig.pool_tries), fitted on half 0 in the bins they are tried in: sloped ones in the
// noisy bins, where the lobes change their shape from bin to bin faster than the noise hides;
// flat ones where the half-table escapes cannot carry the chosen size (capped_by_escapes),
// whatever the family, and the exit distribution changes slowly with alpha. Each bin keeps a
// pool where it gains held-out NLL over the choice so far (pooled_gain: its own escapes and,
// at half weight, its neighbours'). `pools` and the choice's half-0 fits and score are updated
// bin by bin.
void wide_pooling(const Escapes& e, const FitSettings& s, const DirectionGrid& grid, const QuadratureLevels& levels,
                  SizeChoice& choice, std::vector<PoolTry>& pools);

// Each bin's half-table lobes (standing still) as a turning model blends them into the bins
// within `width` of it: bin j in bin b turned by bin j's rate from j's middle to b's (the middle
// of the exit angles the blend spreads it over), hemispherical lobes with bin j's outward factor
// turned with them, as the sampler turns them. Scored at their own bin instead, a neighbour's
// peak lies a bin's turn away (6 degrees near the axis at tau 1 g 0.9), and the held-out half
// called blends worse that bring the model closer to the reference (docs/studies/2026-12-fit-measurements.md,
// "Densities that turn with the exit point, and blends of turning bins"). Each pair once, the bins in parallel.
struct TurnedNeighbours {
  int width = 0;
  std::vector<std::vector<std::vector<double>>> cells;  // [b][j - b + width]
  const std::vector<double>& at(int j, int b) const { return cells[std::size_t(b)][std::size_t(j - b + width)]; }
};

TurnedNeighbours turned_neighbours(const BinFits& fits, const std::vector<BinTurn>& turns, const QuadratureLevels& levels,
                                   int width, const FitSettings& s);

// Widths by bin: each bin takes the width whose held-out gain over none, summed over the bins
// within kConfig.blend_reach at hat weights 1 - |j - b| / (reach + 1), is largest (none where no
// width gains): a bin's own gain is the score of a few hundred escapes, its neighbours' say what
// a bin's cannot.
std::vector<int> widths_by_bin(const std::vector<HeldOut>& blended);

// The held-out scores of a model whose bin b is blended at widths[b].
HeldOut scores_at_widths(const std::vector<HeldOut>& blended, const std::vector<int>& widths);

// The blend widths, from the held-out NLL of the half-0 fits behind `flat` (its per-bin cell
// log-probabilities) with each bin's density blended as a model of each width 0 .. max_width
// blends it (tilts from half 0; in turning models each neighbour's density as the sampler turns
// it into the bin, `turned`). Blending adds no parameter, but a width is kept only where its
// held-out gain over none exceeds kConfig.blend_standard_errors standard errors; among the
// widths so kept the lowest NLL wins, one for every bin. Widths by bin replace it where they gain
// over it by that margin too (they are chosen on the half that scores them, so a small gain is
// their selection's; never without s.blend_by_bin). Near the axis of a forward medium the
// density changes its shape from bin to bin and wants a narrow blend, far from it the bins are
// noisy and want the widest; where the widest suits every bin the gain stays within noise and
// one width is kept. Fills `r`'s blend fields; returns the widths per bin (empty: none).
std::vector<int> choose_blend(const Escapes& e, const HeldOut& flat, const FitSettings& s, const TurnedNeighbours& turned,
                              FitReport& r);

// How each bin borrows from its neighbours: the pools its final fit reaches into, and the
// width of the blend its sampler spreads it with. vmf/hvmf auto: pooling (choose_pooling) and,
// for hvmf, wider pools bin by bin (wide_pooling; with plain lobes they came out worse on one
// medium of the study, docs/studies/2026-12-fit-measurements.md, "Pools chosen bin by bin");
// every auto model: the blend widths (choose_blend), each neighbour turned as the sampler turns
// it. Updates the choice's size, fits and score where a pool wins.
struct Neighbours {
  Pooling pool;
  std::vector<int> blend_widths;  // per bin; empty: none
};

Neighbours choose_neighbours(const Escapes& e, const FitSettings& s, const DirectionGrid& grid,
                             const QuadratureLevels& levels, SizeChoice& choice, FitReport& r);

// The exit points inside each bin: the alpha marginal (smoothed unless ablated) and each bin's
// tilt. For vMF lobes, also how each bin's density turns with them (set on `e`): the final fit
// sees a bin's counts as its density averaged over its exit points, turned as the sampler turns
// it.
struct AlphaShape {
  AlphaMarginal marginal;
  std::vector<double> tilts;
};

AlphaShape alpha_shape(Escapes& e, const FitSettings& s);

// The model of the final fits: the medium, the singular parts and the rest's probabilities
// (rest_probabilities), the alpha marginal, tilts, turns and blends, and each bin's lobes or
// smoothed SH (compressed across alpha where asked).
StfModel assemble_model(const Escapes& e, const FitSettings& s, const AlphaShape& alpha, const SizeChoice& choice,
                        const Neighbours& near, const BinFits& fits);

// Per bin, the model as a sampler uses it against the full table: escapes, lobes with weight,
// Poisson deviance and Pearson chi^2 per degree of freedom (fitted bins only).
void diagnose(const BinFits& fits, const FitSettings& s, const StfModel& m, const QuadratureLevels& levels, int size,
              FitReport& r);

// Area-uniform alpha marginal: for a model of nothing escaping.
std::vector<double> uniform_alpha(const std::vector<double>& edges);

}  // namespace stf::fit::stages
