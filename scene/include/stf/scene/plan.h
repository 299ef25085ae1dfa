// Planning a scene: which tables to compute, share, take from the cache or skip, and why.
//
// Each medium becomes (albedo, g) and a range of optical radii tau = sigma_t * r over the
// radii a renderer will use. The range is covered by a family of tau values shared by all
// media: tau_skip * tau_ratio^k (k = 0, 1, ...), the largest at or below the smallest tau
// and every one up to the largest, so that at any free radius the lookup (stf/lookup.h) finds
// a sphere between 1 / tau_ratio and 1 times the one that fits. Media with equal (tau,
// albedo, g) share an entry (media differing only by scale); a medium whose largest tau is
// below tau_skip gets none (stepping through shells does not pay off: the renderer tracks it
// directly). Entries are cached under a key of every input and setting.
//
// With a tolerance, each entry's alpha bins, direction grid, model size and paths are the
// least that a certified bound puts within it (stf/measure/tolerance.h), found while computing; the
// plan lists the settings as upper limits until the entry is cached, then what it chose.
#pragma once

#include <string>
#include <vector>

#include "stf/scene/scene.h"

namespace stf::scene {

// What an entry is computed at: the settings (upper limits under a tolerance) until its fit
// is in the cache, then what that fit used.
struct Resolution {
  std::string grid;
  int alpha_bins = 0;
  std::string model;       // "vmf:4", "sh:8"; "vmf:auto" etc. before a fit chose
  std::int64_t paths = 0;  // per table
  std::int64_t bytes = 0;  // packed model; 0 before the fit
  double tv_bound = -1;    // certified TV bound under a tolerance; -1 when none
  bool tolerance_met = false;
  bool measured = false;   // read from the cached fit
};

struct PlanEntry {
  double tau = 0, albedo = 0, g = 0;
  std::vector<std::string> media;
  std::string action;  // "compute", "cached" or "skip"
  std::string reason;
  std::string key;     // cache key; empty for skipped media
  Resolution resolution;
};

struct Plan {
  Settings settings;
  std::string cache_dir;
  std::vector<PlanEntry> entries;
};

Plan make_plan(const Scene& scene, const std::string& cache_dir);
// The plan as JSON: per entry also `tolerance_met` and `tv_bound` (null until certified, or
// without a tolerance).
std::string plan_json(const Plan& plan);
// Entries certified under the scene's tolerance but not within it (their bound is the lowest
// the limits allowed).
std::vector<const PlanEntry*> unmet_entries(const Plan& plan);
// Whether `before` (the plan a build started from) had `e` to compute: what a build warns of
// once, when it computes it, and not again when it finds it cached.
bool computed_by(const Plan& before, const PlanEntry& e);
std::string plan_table(const Plan& plan);

// Cache files of an entry.
std::string table_path(const Plan& plan, const PlanEntry& e);
std::string model_path(const Plan& plan, const PlanEntry& e);

}  // namespace stf::scene
