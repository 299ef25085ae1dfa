#include "build.h"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <stdexcept>

#include "fit_table.h"
#include "model_io.h"
#include "precompute.h"
#include "stf/pack.h"

namespace stf::scene {

namespace {

// Writes through `write(temp)` and renames into place: a cache holds whole files or none.
template <typename Write>
void write_atomically(const std::string& path, Write write) {
  const std::string temp = path + ".tmp-" + std::to_string(::getpid());
  try {
    write(temp);
  } catch (...) {
    std::remove(temp.c_str());
    throw;
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    std::remove(temp.c_str());
    throw std::runtime_error("cannot move " + temp + " to " + path);
  }
}

void compute(const Plan& plan, const PlanEntry& e, int threads, const std::atomic<bool>* cancel) {
  const Settings& s = plan.settings;
  PrecomputeSettings ps;
  ps.paths = s.paths;
  ps.grid = s.grid;
  ps.alpha_bins = s.alpha_bins;
  ps.seed = s.seed;
  ps.threads = threads;
  std::optional<Table> table = precompute({e.albedo * e.tau, (1 - e.albedo) * e.tau, e.g, 1}, ps, cancel);
  if (!table) throw std::runtime_error("interrupted; finished entries stay in the cache");
  write_atomically(table_path(plan, e), [&](const std::string& p) { write_table(*table, p); });
  fit::FitSettings fs = fit::parse_model_spec(s.model);
  fs.threads = threads;
  fs.cancel = cancel;
  fit::FitReport report;
  StfModel model = fit::fit_table(*table, fs, &report);
  if (cancel && *cancel) throw std::runtime_error("interrupted; finished entries stay in the cache");
  write_atomically(model_path(plan, e), [&](const std::string& p) {
    fit::write_model(model, report, {s.model, table_path(plan, e), &*table}, p);
  });
}

}  // namespace

int build(const Scene& scene, const Plan& plan, const std::string& pack_path, int threads, const BuildProgress& progress,
          const std::atomic<bool>* cancel) {
  ::mkdir(plan.cache_dir.c_str(), 0755);
  int to_compute = 0, done = 0;
  for (const PlanEntry& e : plan.entries) to_compute += e.action == "compute";
  for (const PlanEntry& e : plan.entries) {
    if (e.action != "compute") continue;
    if (progress) progress(done, to_compute, e);
    compute(plan, e, threads, cancel);
    ++done;
  }
  std::vector<PackEntry> pack;
  for (const Medium& m : scene.media)
    for (const PlanEntry& e : plan.entries) {  // entries of one medium are in increasing tau
      if (e.action == "skip" || std::find(e.media.begin(), e.media.end(), m.name) == e.media.end()) continue;
      pack.push_back({m.name, fit::read_model(model_path(plan, e))});
    }
  std::vector<std::uint8_t> bytes = write_pack(pack);
  write_atomically(pack_path, [&](const std::string& p) {
    std::ofstream f(p, std::ios::binary);
    f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    if (!f) throw std::runtime_error("cannot write " + p);
  });
  return done;
}

}  // namespace stf::scene
