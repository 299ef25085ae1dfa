// fit_table(): the pipeline, stage by stage. What each stage takes, returns and chooses is in
// fit_stages.h; docs/fit.md gives their order and selection rules.
#include "stf/fit/fit_table.h"

#include <chrono>

#include "stf/fit/expected_singular.h"
#include "fit_stages.h"
#include "stf/core/clock.h"

namespace stf::fit {

using namespace stages;

StfModel fit_table(const Table& t, const FitSettings& s, FitReport* report) {
  if (std::string why = settings_error(t, s); !why.empty()) throw std::invalid_argument(why);
  if (wants_expected_singular_parts(t)) return fit_table(with_expected_singular_parts(t), s, report);
  auto start = std::chrono::steady_clock::now();
  FitReport local;
  FitReport& r = report ? *report : local;
  r = FitReport{};
  std::unique_ptr<DirectionGrid> grid = make_grid(t.grid);

  // Escapes: everything is fitted and chosen on the escapes folded over the mirror symmetry
  // (not where the uncollided escapes are unknown: they would be folded off the pole); the
  // diagnostics are against the table as it is.
  Escapes seen{t, s.fold_mirror && t.uncollided_half[0] >= 0 ? mirror_cells(*grid) : std::vector<std::int64_t>{}};
  if (s.kind == ModelKind::kVmf && s.lifted) seen.set_lifted();
  // Alpha: the marginal, the tilts and (vMF) the turns.
  const AlphaShape alpha = alpha_shape(seen, s);
  const QuadratureLevels levels(*grid);
  // Family and size, on the held-out half.
  SizeChoice choice = choose_size(seen, s, *grid, levels, r);
  if (cancelled(s)) return {};
  // Neighbours: pools and blends.
  const Neighbours near = choose_neighbours(seen, s, *grid, levels, choice, r);
  if (cancelled(s)) return {};
  // The final fit on the whole table, from the chosen half-table fits.
  std::unique_ptr<ShProjector> projector;
  if (s.kind == ModelKind::kSh) projector = std::make_unique<ShProjector>(*grid, choice.size);
  const BinFits fits = fit_bins(
      seen, {-1, choice.size, projector.get(), choice.fits.status.empty() ? nullptr : &choice.fits, &near.pool}, levels,
      s);
  if (cancelled(s)) return {};
  // Outcomes (singular parts, the rest, absorption) and directions make the model.
  StfModel m = assemble_model(seen, s, alpha, choice, near, fits);
  // Report: diagnostics against the full table, with the model as a sampler will use it.
  diagnose(fits, s, m, levels, choice.size, r);
  r.chosen_size = choice.size;
  r.singular_parts = singular_parts_source(t);
  r.heldout_halves = t.halves == Halves::kTallied ? "tallied" : t.halves == Halves::kThinned ? "thinned" : "none";
  r.pools = near.pool.bin;
  r.smoothing = choice.smoothing.t;
  r.alpha_penalty = alpha.marginal.bin_escapes.empty() ? -1 : alpha.marginal.penalty;
  r.lanczos_window = choice.smoothing.lanczos;
  r.fit_time_s = seconds_since(start);
  return m;
}

}  // namespace stf::fit
