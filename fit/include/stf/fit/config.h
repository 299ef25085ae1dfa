// The fit pipeline's tuning, in one place: what each number decides. What each was measured to
// buy is in docs/studies/ (docs/fit.md, "Settings").
#pragma once

namespace stf::fit {

// How a bin's lobes are fitted to its neighbours' escapes: alone (width 0), or with the bins
// within `width` on either side, bin b +- d weighted pool_weight(width, d), and where `sloped`
// with the lobes continued linearly in alpha (VmfFitOptions::sloped).
struct PoolTry {
  int width = 0;
  bool sloped = false;
  bool operator==(const PoolTry&) const = default;
};

struct FitConfig {
  // Pools (fit_neighbours.cpp, fit_bins.cpp).
  double pool_below_escapes = 4e4;   // bins with fewer escapes (two or more collisions, both halves) are pooled
  double escapes_per_lobe = 50;      // a bin gets at most one lobe per this many escapes it is fitted to
  PoolTry pool_tries[2] = {{3, true}, {4, false}};  // wider pools tried bin by bin: sloped, then flat
  int pool_try_iterations = 15;      // a trial pool only ranks pools: its fits stop this early
  double sloped_pool_escapes_per_lobe = 400;  // bins with fewer escapes per lobe try sloped pools
  // A bin's pool gain also counts its two neighbours' at this weight: one bin's held-out score
  // is one noisy number, and neighbouring bins differ little.
  double neighbour_gain_weight = 0.5;
  double outward_cache_bytes = 256e6;  // the most memory a pass keeps every bin's outward factors in
  // Headings and turns (fit_alpha.cpp).
  int heading_window = 5;    // bins on either side of the local quadratic that smooths headings
  double max_fitted_turn = 4;  // radians of turn per radian of alpha, at most
  // Blends (fit_blend.cpp). A width is kept where its held-out gain over none exceeds this many
  // standard errors: the held-out NLL, summed over all bins, can miss a loss in the heavy bins
  // by a nat or two.
  double blend_standard_errors = 2;
  int blend_reach = 3;  // widths by bin sum the gains of the bins within this reach, at hat weights
};

inline constexpr FitConfig kConfig{};

}  // namespace stf::fit
