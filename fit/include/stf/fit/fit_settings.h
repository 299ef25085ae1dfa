// What a fit is asked to do (FitSettings, parsed from a model spec) and what it reports
// (FitReport): the types every stage of the fit and every caller share.
#pragma once

#include <atomic>
#include <functional>
#include <string>
#include <vector>

#include "stf/core/parallel.h"
#include "stf/fit/config.h"
#include "stf/model.h"

namespace stf::fit {

struct FitSettings {
  ModelKind kind = ModelKind::kVmf;
  int size = 4;            // lobes (vmf) or band limit (sh)
  bool automatic = false;  // vmf:auto / sh:auto: size chosen by held-out error
  bool hemispherical = false;  // hvmf: vMF lobes times each bin's outward cosine (stf/hemisphere.h)
  bool lifted = false;  // lvmf: vMF lobes lifted to each exit point's outward hemisphere (StfModel::lifted)
  int min_escapes = 10;    // bins with fewer escapes borrow their neighbour's model
  int alpha_degree = -1;   // sh: >= 0 replaces the bins' coefficients by a Chebyshev series in cos(alpha)
  int max_blend = StfModel::kMaxBlend;  // auto: the widest alpha blend tried (StfModel::alpha_blend)
  // vmf/hvmf auto: whether fitting each bin together with its neighbours' escapes, turned to
  // its heading (pool_weight(1, 1)), is tried on held-out data.
  bool pool_neighbours = true;
  // Whether the escapes are folded over their mirror symmetry as they are fitted
  // (fold_over_mirror).
  bool fold_mirror = true;
  // Whether the alpha marginal of the escapes after two or more collisions is smoothed across
  // the bins (smooth_alpha_marginal) rather than taken from the bins' tallied totals.
  bool smooth_alpha = true;
  // vmf/hvmf: whether each bin's density turns with the exit angle inside the bin, at the rate
  // its smoothed heading turns (StfModel::alpha_turn, alpha_turns).
  bool turn = true;
  // Whether each bin's exit points get a fitted tilt in area (StfModel::alpha_tilt) rather than
  // spreading uniformly.
  bool tilt = true;
  // hvmf auto: whether flat pools wider than the nearest neighbours are tried bin by bin
  // (wide_pooling).
  bool wide_pools = true;
  // auto: whether blend widths may differ from bin to bin (StfModel::alpha_blend_width) rather
  // than one width for all.
  bool blend_by_bin = true;
  // How the fit runs: its threads, the flag after which fit_table returns early with a model
  // that must be thrown away, and whom it tells, as bins are done, the step it is on ("fits,
  // size 4, half 0", "final fit", ...) and how many of its bins are done.
  RunContext run;
};

// Parses "auto" (what the project recommends: hvmf:auto), "vmf:K", "vmf:auto", "hvmf:K",
// "hvmf:auto", "sh:L", "sh:auto" (1 <= K <= 16, 0 <= L <= 32). Throws std::invalid_argument
// naming --model and what is allowed.
FitSettings parse_model_spec(const std::string& spec);

// The mechanisms the fit can be run without (stf fit --ablate, for bench/ablation.py), each with
// the setting that turns it off.
struct Ablation {
  const char* name;
  void (*off)(FitSettings&);
};
inline constexpr Ablation kAblations[] = {
    {"mirror", [](FitSettings& s) { s.fold_mirror = false; }},
    {"pooling", [](FitSettings& s) { s.pool_neighbours = false; }},
    {"wide-pools", [](FitSettings& s) { s.wide_pools = false; }},
    {"alpha-smoothing", [](FitSettings& s) { s.smooth_alpha = false; }},
    {"tilt", [](FitSettings& s) { s.tilt = false; }},
    {"turn", [](FitSettings& s) { s.turn = false; }},
    {"blend", [](FitSettings& s) { s.max_blend = 0; }},
    {"blend-by-bin", [](FitSettings& s) { s.blend_by_bin = false; }},
};

// Turns off the mechanisms named in `list` (comma separated, from kAblations). Throws
// std::invalid_argument naming --ablate, what is allowed and the name it did not know.
void ablate(FitSettings& settings, const std::string& list);

// The rows of the table an SH model of this band limit is drawn from (StfModel::sh_nz): fine
// enough for its finest detail.
inline int sh_table_rows(int band_limit) { return band_limit * 4 > 32 ? band_limit * 4 : 32; }

// Candidate sizes tried by vmf:auto and sh:auto.
std::vector<int> auto_candidates(ModelKind kind);

struct BinDiagnostics {
  double escapes = 0;   // the bin's escaped weight in the table
  int components = 0;   // lobes with weight, or the band limit
  double deviance = 0;  // Poisson deviance against the table
  // Pearson chi^2 per degree of freedom against the table, in fitted bins only: -1 in bins
  // that borrow a neighbour's model or are empty (their model was not fitted to their counts).
  double chi2_dof = -1;
};

struct FitReport {
  std::vector<BinDiagnostics> bins;
  std::vector<int> candidates;           // auto: sizes tried
  std::vector<double> heldout_nll;       // auto: held-out negative log-likelihood per size
  std::vector<double> heldout_nll_error; // auto: its standard error against the best
  int chosen_size = 0;
  // auto: held-out NLL of the chosen size per blend width 0 .. kMaxBlend (StfModel::alpha_blend)
  std::vector<double> blend_heldout_nll;
  std::vector<double> blend_heldout_nll_error;  // and its standard error against width 0's
  // auto: the one width for every bin the held-out NLLs chose; the held-out NLL that widths
  // chosen bin by bin (StfModel::alpha_blend_width) gain over it, and its standard error: the
  // widths by bin are kept where the gain exceeds two of them.
  int blend_width = 0;
  double blend_by_bin_gain = 0;
  double blend_by_bin_error = 0;
  // vmf/hvmf auto, when neighbour pooling was tried: the sizes and their held-out NLL fitted
  // with the neighbours' escapes (pool_sizes), against the chosen unpooled size's; and the
  // neighbours' weight the final fit used (0: each bin alone).
  std::vector<int> pool_sizes;
  std::vector<double> pool_heldout_nll;
  double neighbour_weight = 0;
  // vmf/hvmf auto: per bin, how its fit reached for its neighbours' escapes.
  std::vector<PoolTry> pools;
  double smoothing = 0;         // sh: heat-kernel t chosen on the held-out half
  bool lanczos_window = false;  // sh: whether the Lanczos window was chosen there too
  // The roughness penalty of the smoothed alpha marginal (smooth_alpha_marginal); -1: the
  // bins' tallied totals were kept.
  double alpha_penalty = -1;
  // How the singular parts were taken out before the smooth fit (singular_parts_source).
  std::string singular_parts;
  // Where the held-out halves came from: "tallied" (by the walk, or given in the file), "thinned"
  // (Binomial(n, 1/2) of whole-number counts) or "none" (weights split evenly).
  std::string heldout_halves;
  double fit_time_s = 0;
};

}  // namespace stf::fit
