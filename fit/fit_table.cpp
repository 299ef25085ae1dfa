// fit_table(): the pipeline, stage by stage. What each stage takes, returns and chooses is in
// fit_stages.h; docs/fit.md gives their order and selection rules.
#include "fit_table.h"

#include <chrono>

#include "expected_singular.h"
#include "fit_stages.h"

namespace stf::fit {

using namespace stages;

namespace {

// --model auto: hemispherical lobes (hvmf) and SH at their held-out sizes, scored on the same
// held-out half; the one with the lower held-out negative log-likelihood is kept (with its
// report).
StfModel fit_any_family(const Table& t, const FitSettings& s, FitReport& r) {
  FitSettings one = s;
  one.any_family = false;
  FitReport reports[2];
  StfModel models[2];
  double nll[2];
  for (int i = 0; i < 2; ++i) {
    one.kind = i == 0 ? ModelKind::kVmf : ModelKind::kSh;
    one.hemispherical = i == 0;  // the lobes in the form that respects the outward hemisphere
    models[i] = fit_table(t, one, &reports[i]);
    if (cancelled(s)) return {};
    const FitReport& ri = reports[i];
    auto chosen = std::find(ri.candidates.begin(), ri.candidates.end(), ri.chosen_size) - ri.candidates.begin();
    nll[i] = ri.heldout_nll[std::size_t(chosen)];
  }
  const int best = nll[1] < nll[0] ? 1 : 0;
  r = reports[best];
  r.fit_time_s = reports[0].fit_time_s + reports[1].fit_time_s;
  r.family_heldout_nll = {nll[0], nll[1]};
  return models[best];
}

}  // namespace

StfModel fit_table(const Table& t, const FitSettings& s, FitReport* report) {
  if (std::string why = settings_error(t, s); !why.empty()) throw std::invalid_argument(why);
  if (wants_expected_singular_parts(t)) return fit_table(with_expected_singular_parts(t), s, report);
  if (s.any_family) {
    FitReport local;
    return fit_any_family(t, s, report ? *report : local);
  }
  auto start = std::chrono::steady_clock::now();
  FitReport local;
  FitReport& r = report ? *report : local;
  r = FitReport{};
  std::unique_ptr<DirectionGrid> grid = make_grid(t.grid);

  // Escapes: everything is fitted and chosen on the escapes folded over the mirror symmetry
  // (not where the uncollided escapes are unknown: they would be folded off the pole); the
  // diagnostics are against the table as it is.
  Escapes seen{t, s.fold_mirror && t.uncollided_half[0] >= 0 ? mirror_cells(*grid) : std::vector<std::int64_t>{}};
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
  r.fit_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return m;
}

}  // namespace stf::fit
