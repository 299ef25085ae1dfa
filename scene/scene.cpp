#include "stf/scene/scene.h"

#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <set>

#include "stf/fit/fit_table.h"
#include "stf/core/grid.h"
#include "stf/precompute/precompute.h"
#include "toml_values.h"

namespace stf::scene {

namespace {

Settings read_settings(const toml::value& t) {
  Settings s;
  check_keys(t, "settings.", {"paths", "grid", "alpha_bins", "model", "seed", "tau_skip", "tau_ratio", "tolerance"});
  if (t.contains("paths")) {
    double p = number(t.at("paths"), "settings.paths");
    expect(p >= 1 && p <= 1e12 && p == std::floor(p), t.at("paths"), "settings.paths: must be a whole number in 1..1e12");
    s.paths = std::int64_t(p);
  }
  if (t.contains("grid")) {
    s.grid = text(t.at("grid"), "settings.grid");
    try {
      make_grid(s.grid);
    } catch (const std::invalid_argument& e) {
      error_at(t.at("grid"), std::string("settings.grid: ") + e.what());
    }
  }
  if (t.contains("alpha_bins")) {
    double b = number(t.at("alpha_bins"), "settings.alpha_bins");
    expect(b >= 1 && b <= 100000 && b == std::floor(b), t.at("alpha_bins"), "settings.alpha_bins: must be a whole number in 1..100000");
    s.alpha_bins = int(b);
  }
  if (double bytes = table_bytes(grid_cell_count(s.grid), s.alpha_bins); bytes > kMaxTableBytes)
    error_at(t.contains("grid") ? t.at("grid") : t.at("alpha_bins"),
             "settings.grid, settings.alpha_bins: a table of " + s.grid + " x " + std::to_string(s.alpha_bins) +
                 " alpha bins needs about " + fmt::format("{:g}", bytes / (1 << 30)) + " GiB; stf keeps tables up to " +
                 fmt::format("{:g}", kMaxTableBytes / (1 << 30)) + " GiB");
  if (t.contains("model")) {
    s.model = text(t.at("model"), "settings.model");
    try {
      fit::parse_model_spec(s.model);
    } catch (const std::invalid_argument& e) {
      error_at(t.at("model"), std::string("settings.model: ") + e.what());
    }
  }
  if (t.contains("seed")) {
    double seed = number(t.at("seed"), "settings.seed");
    expect(seed >= 0 && seed <= 9e18 && seed == std::floor(seed), t.at("seed"), "settings.seed: must be a whole number >= 0");
    s.seed = std::int64_t(seed);
  }
  if (t.contains("tau_skip")) {
    s.tau_skip = number(t.at("tau_skip"), "settings.tau_skip");
    expect(s.tau_skip > 0 && std::isfinite(s.tau_skip), t.at("tau_skip"), "settings.tau_skip: must be > 0");
  }
  if (t.contains("tolerance")) {
    s.tolerance = number(t.at("tolerance"), "settings.tolerance");
    expect(s.tolerance > 0 && s.tolerance < 1, t.at("tolerance"), "settings.tolerance: must be a TV distance in (0, 1)");
  }
  if (t.contains("tau_ratio")) {
    s.tau_ratio = number(t.at("tau_ratio"), "settings.tau_ratio");
    expect(s.tau_ratio > 1.01 && s.tau_ratio <= 100, t.at("tau_ratio"), "settings.tau_ratio: must be in (1.01, 100]");
  }
  return s;
}

Medium read_medium(const toml::value& t, std::size_t index) {
  const std::string where = "media[" + std::to_string(index) + "].";
  expect(t.is_table(), t, where.substr(0, where.size() - 1) + ": expected a table");
  check_keys(t, where, {"name", "sigma_s", "sigma_a", "g", "radius_min", "radius_max", "size"});
  Medium m;
  m.line = int(t.location().line());
  m.name = name_text(require(t, "name", where), where + "name");
  m.sigma_s = number(require(t, "sigma_s", where), where + "sigma_s");
  expect(m.sigma_s >= 0 && std::isfinite(m.sigma_s), t.at("sigma_s"), where + "sigma_s: must be a finite number >= 0");
  m.sigma_a = number(require(t, "sigma_a", where), where + "sigma_a");
  expect(m.sigma_a >= 0 && std::isfinite(m.sigma_a), t.at("sigma_a"), where + "sigma_a: must be a finite number >= 0");
  expect(m.sigma_s + m.sigma_a > 0, t, where + "sigma_s, sigma_a: must not both be 0");
  m.g = number(require(t, "g", where), where + "g");
  expect(m.g > -1 && m.g < 1, t.at("g"), where + "g: must be in (-1, 1)");
  if (t.contains("size")) {
    expect(!t.contains("radius_min") && !t.contains("radius_max"), t.at("size"),
           where + "size: give either size or radius_min and radius_max");
    double size = number(t.at("size"), where + "size");
    expect(size > 0 && std::isfinite(size), t.at("size"), where + "size: must be > 0");
    m.radius_max = size / 2;
    m.radius_min = m.radius_max / 64;
  } else {
    m.radius_min = number(require(t, "radius_min", where), where + "radius_min");
    m.radius_max = number(require(t, "radius_max", where), where + "radius_max");
    expect(m.radius_min > 0 && m.radius_min <= m.radius_max && std::isfinite(m.radius_max), t.at("radius_max"),
           where + "radius_min, radius_max: need 0 < radius_min <= radius_max");
  }
  // Checked here, not in the middle of a build: the largest table the plan could ask for.
  const char* key = t.contains("size") ? "size" : "radius_max";
  const double tau_max = (m.sigma_s + m.sigma_a) * m.radius_max;
  expect(tau_max <= kMaxTau, t.at(key),
         where + key + ": the largest optical radius (sigma_s + sigma_a) * radius_max is " + fmt::format("{:g}", tau_max) +
             ", above the largest table stf computes (tau " + fmt::format("{:g}", kMaxTau) + ")");
  return m;
}

}  // namespace

Scene read_scene(const std::string& path) {
  const toml::value root = parse_toml(path);
  Scene scene;
  scene.path = path;
  check_keys(root, "", {"settings", "media"});
  if (root.contains("settings")) {
    expect(root.at("settings").is_table(), root.at("settings"), "settings: expected a table");
    scene.settings = read_settings(root.at("settings"));
  }
  if (!root.contains("media") || !root.at("media").is_array() || root.at("media").as_array().empty())
    throw SceneError(path + ":1: media: the scene needs at least one [[media]] table");
  std::set<std::string> names;
  const auto& media = root.at("media").as_array();
  for (std::size_t i = 0; i < media.size(); ++i) {
    Medium m = read_medium(media[i], i);
    if (!names.insert(m.name).second) error_at(media[i].at("name"), "media[" + std::to_string(i) + "].name: '" + m.name + "' is used twice");
    scene.media.push_back(m);
  }
  return scene;
}

}  // namespace stf::scene
