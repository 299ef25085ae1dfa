#include "stf/scene/plan.h"

#include <fmt/format.h>

#include <sys/stat.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>
#include <tuple>

#include "stf/fit/model_io.h"

namespace stf::scene {

bool computed_by(const Plan& before, const PlanEntry& e) {
  return std::any_of(before.entries.begin(), before.entries.end(),
                     [&](const PlanEntry& b) { return b.key == e.key && b.action == "compute"; });
}

namespace {

std::string cache_key(const Settings& s, double tau, double albedo, double g) {
  std::string text = "stf " STF_VERSION ";tau=" + fmt::format("{:.12g}", tau) + ";albedo=" + fmt::format("{:.12g}", albedo) + ";g=" + fmt::format("{:.12g}", g) +
                     ";paths=" + std::to_string(s.paths) + ";grid=" + s.grid + ";bins=" + std::to_string(s.alpha_bins) +
                     ";model=" + s.model + ";seed=" + std::to_string(s.seed) +
                     (s.tolerance > 0 ? ";tolerance=" + fmt::format("{:.12g}", s.tolerance) : "");
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char c : text) h = (h ^ c) * 0x100000001b3ull;
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

bool exists(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0;
}

Resolution from_settings(const Settings& s) {
  Resolution r;
  r.grid = s.grid, r.alpha_bins = s.alpha_bins, r.model = s.model, r.paths = s.paths;
  return r;
}

Resolution from_fit(const std::string& model_file) {
  fit::ModelSummary m = fit::read_model_summary(model_file);
  Resolution r;
  r.grid = m.grid, r.alpha_bins = m.alpha_bins, r.model = m.kind + ":" + std::to_string(m.size), r.paths = m.paths;
  r.bytes = m.bytes;
  if (m.tolerance > 0) r.tv_bound = m.tv_bound, r.tolerance_met = m.tolerance_met;
  r.measured = true;
  return r;
}

std::string resolution_text(const Resolution& r, const Settings& s) {
  char buf[256];
  if (!r.measured)
    std::snprintf(buf, sizeof buf, s.tolerance > 0 ? "up to %s, %d bins, %s, %.3g paths" : "%s, %d bins, %s, %.3g paths",
                  r.grid.c_str(), r.alpha_bins, r.model.c_str(), double(r.paths));
  else if (r.tv_bound >= 0)
    std::snprintf(buf, sizeof buf, "%s, %d bins, %s, %.3g paths, TV <= %.3g%s", r.grid.c_str(), r.alpha_bins,
                  r.model.c_str(), double(r.paths), r.tv_bound, r.tolerance_met ? "" : " (tolerance NOT met)");
  else
    std::snprintf(buf, sizeof buf, "%s, %d bins, %s, %.3g paths", r.grid.c_str(), r.alpha_bins, r.model.c_str(),
                  double(r.paths));
  return buf;
}

}  // namespace

std::string table_path(const Plan& plan, const PlanEntry& e) { return plan.cache_dir + "/" + e.key + ".table.h5"; }
std::string model_path(const Plan& plan, const PlanEntry& e) { return plan.cache_dir + "/" + e.key + ".model.h5"; }

Plan make_plan(const Scene& scene, const std::string& cache_dir) {
  Plan plan;
  plan.settings = scene.settings;
  plan.cache_dir = cache_dir;
  const Settings& s = scene.settings;
  std::map<std::tuple<std::string, std::string, std::string>, std::size_t> shared;
  for (const Medium& m : scene.media) {
    const double sigma_t = m.sigma_s + m.sigma_a, albedo = m.sigma_s / sigma_t;
    const double tau_min = sigma_t * m.radius_min, tau_max = sigma_t * m.radius_max;
    if (tau_max < s.tau_skip) {
      plan.entries.push_back({tau_max, albedo, m.g, {m.name}, "skip",
                              "largest optical radius " + fmt::format("{:.12g}", tau_max) + " is below tau_skip " + fmt::format("{:.12g}", s.tau_skip) +
                                  ": the renderer tracks this medium directly",
                              "", {}});
      continue;
    }
    // The family member at or below tau_min (but not below tau_skip), then up to tau_max.
    int k0 = std::max(0, int(std::floor(std::log(tau_min / s.tau_skip) / std::log(s.tau_ratio) + 1e-9)));
    for (int k = k0;; ++k) {
      const double tau = s.tau_skip * std::pow(s.tau_ratio, k);
      if (tau > tau_max * (1 + 1e-12)) break;
      auto id = std::make_tuple(fmt::format("{:.12g}", tau), fmt::format("{:.12g}", albedo), fmt::format("{:.12g}", m.g));
      if (auto it = shared.find(id); it != shared.end()) {
        plan.entries[it->second].media.push_back(m.name);
        continue;
      }
      PlanEntry e{tau, albedo, m.g, {m.name}, "compute", "", cache_key(s, tau, albedo, m.g), {}};
      e.resolution = from_settings(s);
      if (exists(model_path(plan, e))) {
        e.resolution = from_fit(model_path(plan, e));
        e.action = "cached";
        e.reason = "a table and fit with the same inputs and settings are in the cache";
      } else {
        e.reason = "covers free radii from " + fmt::format("{:.12g}", tau / sigma_t) + " in " + m.name + " (tau " + fmt::format("{:.12g}", tau) + ")";
      }
      shared[id] = plan.entries.size();
      plan.entries.push_back(e);
    }
  }
  // A shared entry says so.
  for (PlanEntry& e : plan.entries)
    if (e.media.size() > 1) e.reason += "; shared by " + std::to_string(e.media.size()) + " media";
  return plan;
}

std::vector<const PlanEntry*> unmet_entries(const Plan& plan) {
  std::vector<const PlanEntry*> unmet;
  if (plan.settings.tolerance > 0)
    for (const PlanEntry& e : plan.entries)
      if (e.action != "skip" && e.resolution.measured && !e.resolution.tolerance_met) unmet.push_back(&e);
  return unmet;
}

namespace {

using nlohmann::ordered_json;

// A bound that is not known (no tolerance, not yet measured, not finite) is null.
ordered_json bound_or_null(bool known, double v) { return known && std::isfinite(v) ? ordered_json(v) : ordered_json(nullptr); }

ordered_json entry_json(const PlanEntry& e, const Settings& settings) {
  ordered_json j = {{"tau", e.tau}, {"albedo", e.albedo}, {"g", e.g}, {"action", e.action}, {"reason", e.reason},
                    {"media", e.media}};
  const bool certified = settings.tolerance > 0 && e.resolution.measured;
  if (e.action != "skip") {
    j["tolerance_met"] = certified ? ordered_json(e.resolution.tolerance_met) : ordered_json(nullptr);
    j["tv_bound"] = bound_or_null(certified, e.resolution.tv_bound);
  }
  if (!e.key.empty()) {
    const Resolution& r = e.resolution;
    j["key"] = e.key;
    j["resolution"] = {{"chosen", r.measured}, {"grid", r.grid}, {"alpha_bins", r.alpha_bins}, {"model", r.model},
                       {"paths", r.paths}, {"model_bytes", r.bytes}, {"tv_bound", bound_or_null(r.tv_bound >= 0, r.tv_bound)}};
  }
  return j;
}

}  // namespace

std::string plan_json(const Plan& plan) {
  const Settings& s = plan.settings;
  ordered_json j = {{"settings",
                     {{"paths", s.paths}, {"tolerance", bound_or_null(s.tolerance > 0, s.tolerance)}, {"grid", s.grid},
                      {"alpha_bins", s.alpha_bins}, {"model", s.model}, {"tau_skip", s.tau_skip}, {"tau_ratio", s.tau_ratio}}},
                    {"entries", ordered_json::array()}};
  for (const PlanEntry& e : plan.entries) j["entries"].push_back(entry_json(e, s));
  return j.dump(2) + "\n";
}

std::string plan_table(const Plan& plan) {
  std::ostringstream s;
  char line[512];
  std::snprintf(line, sizeof line, "%-9s %-10s %-9s %-9s %-24s %s\n", "action", "tau", "albedo", "g", "media",
                "reason / resolution");
  s << line;
  for (const PlanEntry& e : plan.entries) {
    std::string media;
    for (const std::string& m : e.media) media += (media.empty() ? "" : ",") + m;
    std::snprintf(line, sizeof line, "%-9s %-10.4g %-9.4g %-9.4g %-24s %s\n", e.action.c_str(), e.tau, e.albedo, e.g,
                  media.c_str(), e.reason.c_str());
    s << line;
    if (!e.key.empty()) s << std::string(64, ' ') << resolution_text(e.resolution, plan.settings) << "\n";
  }
  return s.str();
}

}  // namespace stf::scene
