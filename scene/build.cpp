#include "stf/scene/build.h"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <cstdio>
#include <fstream>
#include <limits>
#include <stdexcept>

#include "stf/core/files.h"
#include "stf/fit/fit_table.h"
#include "stf/core/grid.h"
#include "stf/measure/tolerance.h"
#include "stf/fit/model_io.h"
#include "stf/precompute/precompute.h"
#include "stf/pack.h"

namespace stf::scene {

namespace {

[[noreturn]] void interrupted() { throw std::runtime_error("interrupted; finished entries stay in the cache"); }

// A table of the entry's medium in the unit sphere.
Table walk(const PlanEntry& e, const Settings& s, std::int64_t paths, std::int64_t seed, int threads,
           const std::atomic<bool>* cancel) {
  PrecomputeSettings ps;
  ps.paths = paths;
  ps.grid = s.grid;
  ps.alpha_bins = s.alpha_bins;
  ps.seed = seed;
  ps.run = {threads, cancel, {}};
  std::optional<Table> table = precompute({e.albedo * e.tau, (1 - e.albedo) * e.tau, e.g, 1}, ps);
  if (!table) interrupted();
  return std::move(*table);
}

void store(const Plan& plan, const PlanEntry& e, const Table& table, const StfModel& model, const fit::FitReport& report,
           fit::Provenance provenance) {
  // Each file whole or not at all: a cache never holds half a table.
  write_table(table, table_path(plan, e));
  provenance.source_table = table_path(plan, e);
  fit::write_model(model, report, provenance, model_path(plan, e));
}

// Paths of the first round: the certificate's own noise, 0.5 sqrt(2 sd(chi^2)) with
// sd ~ sqrt(2 cells) / paths over all (alpha bin, cell) pairs, is then about a quarter of the
// tolerance; fewer paths could not certify it whatever the model.
std::int64_t first_round_paths(const Settings& s) {
  std::unique_ptr<DirectionGrid> grid = make_grid(s.grid);
  const double cells = double(s.alpha_bins) * double(grid->cell_count());
  const double paths = 8 * std::sqrt(2 * cells) / (s.tolerance * s.tolerance);
  return std::min(s.paths, std::max(std::int64_t(10'000), std::int64_t(std::ceil(paths / 1e4)) * 10'000));
}

// Rounds of paths, fourfold up to the settings' paths, until a fit is certified within the
// tolerance on a second table (seed + 1) or more paths stop helping; the round with the
// lowest bound is kept either way, marked in the model file.
void compute_to_tolerance(const Plan& plan, const PlanEntry& e, const fit::FitSettings& fs, int threads,
                          const std::atomic<bool>* cancel) {
  const Settings& s = plan.settings;
  struct Round {
    Table table;
    std::int64_t heldout_paths = 0;
    measure::ToleranceFit fit;
  };
  std::optional<Round> best;
  for (std::int64_t paths = first_round_paths(s);; paths = std::min(s.paths, 4 * paths)) {
    Table table = walk(e, s, paths, s.seed, threads, cancel), heldout = walk(e, s, paths, s.seed + 1, threads, cancel);
    measure::ToleranceFit r = measure::fit_to_tolerance(table, heldout, s.tolerance, fs);
    if (cancel && *cancel) interrupted();
    // Four times the paths halve the noise in the bound; a round that gains under 10% is
    // held back by what the model kind cannot represent, and more paths will not help.
    const double previous = best ? best->fit.certificate.tv_bound : std::numeric_limits<double>::infinity();
    const bool stalled = r.certificate.tv_bound > 0.9 * previous, met = r.met;
    if (!best || r.certificate.tv_bound < previous) best = Round{std::move(table), heldout.paths, std::move(r)};
    if (!met && !stalled && paths < s.paths) continue;
    break;
  }
  const measure::ToleranceFit& r = best->fit;
  fit::Provenance provenance;
  provenance.model_spec = s.model, provenance.table = &best->table, provenance.fit_grid = r.fitted.grid;
  provenance.tolerance = s.tolerance, provenance.tv_bound = r.certificate.tv_bound, provenance.tolerance_met = r.met;
  provenance.heldout_table = "seed " + std::to_string(s.seed + 1) + " (not kept)";
  provenance.heldout_paths = best->heldout_paths;
  store(plan, e, best->table, r.model, r.report, provenance);
}

void compute(const Plan& plan, const PlanEntry& e, int threads, const std::atomic<bool>* cancel) {
  const Settings& s = plan.settings;
  fit::FitSettings fs = fit::parse_model_spec(s.model);
  fs.run = {threads, cancel, {}};
  if (s.tolerance > 0) return compute_to_tolerance(plan, e, fs, threads, cancel);
  Table table = walk(e, s, s.paths, s.seed, threads, cancel);
  fit::FitReport report;
  StfModel model = fit::fit_table(table, fs, &report);
  if (cancel && *cancel) interrupted();
  fit::Provenance provenance;
  provenance.model_spec = s.model, provenance.table = &table;
  store(plan, e, table, model, report, provenance);
}

}  // namespace

int compute_entries(const Plan& plan, int threads, const BuildProgress& progress, const std::atomic<bool>* cancel,
                    int part, int parts) {
  ::mkdir(plan.cache_dir.c_str(), 0755);
  std::vector<const PlanEntry*> mine;
  int index = 0;
  for (const PlanEntry& e : plan.entries)
    if (e.action == "compute" && index++ % parts == part) mine.push_back(&e);
  for (std::size_t i = 0; i < mine.size(); ++i) {
    if (progress) progress(int(i), int(mine.size()), *mine[i]);
    compute(plan, *mine[i], threads, cancel);
  }
  return int(mine.size());
}

std::vector<std::uint8_t> scene_pack(const Scene& scene, const Plan& plan) {
  std::vector<PackEntry> pack;
  for (const Medium& m : scene.media)
    for (const PlanEntry& e : plan.entries) {  // entries of one medium are in increasing tau
      if (e.action == "skip" || std::find(e.media.begin(), e.media.end(), m.name) == e.media.end()) continue;
      pack.push_back({m.name, fit::read_model(model_path(plan, e))});
      if (std::string why = pack_entry_error(pack.back()); !why.empty())
        throw std::runtime_error(model_path(plan, e) + " cannot go into a pack: " + why);
    }
  return write_pack(pack);
}

void write_scene_pack(const Scene& scene, const Plan& plan, const std::string& pack_path) {
  const std::vector<std::uint8_t> bytes = scene_pack(scene, plan);
  replace_file(pack_path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

int build(const Scene& scene, const Plan& plan, const std::string& pack_path, int threads, const BuildProgress& progress,
          const std::atomic<bool>* cancel) {
  int computed = compute_entries(plan, threads, progress, cancel);
  write_scene_pack(scene, plan, pack_path);
  return computed;
}

}  // namespace stf::scene
