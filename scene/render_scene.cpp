#include "stf/scene/render_scene.h"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <optional>
#include <set>

#include "toml_values.h"

namespace stf::scene {

namespace {

Vec3 vec3(const toml::value& v, const std::string& name) {
  expect(v.is_array() && v.as_array().size() == 3, v, name + ": expected [x, y, z]");
  const auto& a = v.as_array();
  const Vec3 out{number(a[0], name), number(a[1], name), number(a[2], name)};
  expect(std::isfinite(out.x) && std::isfinite(out.y) && std::isfinite(out.z), v, name + ": must be finite");
  return out;
}

// A point of the scene: within kLargestCoordinate of the origin in each coordinate.
Vec3 position(const toml::value& v, const std::string& name) {
  const Vec3 p = vec3(v, name);
  expect(std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}) <= kLargestCoordinate, v,
         fmt::format("{}: a coordinate beyond +-{:g} (surfaces are traced in float)", name, kLargestCoordinate));
  return p;
}

// A direction of any finite length but 0, as a unit vector: scaled by its largest component
// first, so that neither 1e300 overflows nor 1e-200 underflows.
Vec3 direction(const toml::value& v, const std::string& name) {
  const Vec3 d = vec3(v, name);
  const double largest = std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)});
  expect(largest > 0, v, name + ": must not be 0");
  return normalize((1 / largest) * d);
}

// One number for all three channels, or [r, g, b]; each in [low, high] (closed unless
// `open_high`).
Rgb rgb(const toml::value& v, const std::string& name, double low, double high, bool open_high = false) {
  Rgb out{};
  if (v.is_array()) {
    expect(v.as_array().size() == 3, v, name + ": expected one number or [r, g, b]");
    for (std::size_t c = 0; c < 3; ++c) out[c] = number(v.as_array()[c], name);
  } else {
    out.fill(number(v, name));
  }
  for (double x : out)
    expect(x >= low && (open_high ? x < high : x <= high) && std::isfinite(x), v,
           name + ": must be in [" + fmt::format("{:g}", low) + ", " + fmt::format("{:g}", high) + (open_high ? ")" : "]"));
  return out;
}

double bounded(const toml::value& t, const std::string& key, const std::string& where, double low, double high) {
  const double x = number(t.at(key), where + key);
  expect(x >= low && x <= high, t.at(key), where + key + ": must be in [" + fmt::format("{:g}", low) + ", " + fmt::format("{:g}", high) + "]");
  return x;
}

CameraSpec read_camera(const toml::value& t) {
  check_keys(t, "camera.", {"position", "look_at", "up", "fov", "width", "height"});
  CameraSpec c;
  if (t.contains("position")) c.position = position(t.at("position"), "camera.position");
  if (t.contains("look_at")) c.look_at = position(t.at("look_at"), "camera.look_at");
  c.up = t.contains("up") ? direction(t.at("up"), "camera.up") : normalize(c.up);
  if (t.contains("fov")) c.fov = bounded(t, "fov", "camera.", 0.1, 170);
  if (t.contains("width")) c.width = int(whole_number(t.at("width"), "camera.width", 1, 8192));
  if (t.contains("height")) c.height = int(whole_number(t.at("height"), "camera.height", 1, 8192));
  const Vec3 view = c.look_at - c.position;
  expect(length(view) > 0, t, "camera: position and look_at must differ");
  const double largest = std::max({std::abs(view.x), std::abs(view.y), std::abs(view.z)});
  expect(length(cross(normalize((1 / largest) * view), c.up)) > 1e-9, t.contains("up") ? t.at("up") : t,
         "camera.up: must not be parallel to the view (look_at - position)");
  return c;
}

// An input file named by `v`, resolved against the scene's folder: one that exists and is a
// regular file (a FIFO would block the read, a device never end it).
std::string input_file(const toml::value& v, const std::string& name, const std::string& scene_path) {
  const std::string file = (std::filesystem::path(scene_path).parent_path() / text(v, name)).string();
  struct stat st;
  if (::stat(file.c_str(), &st) != 0)
    error_at(v, name + (errno == ENOENT ? ": no such file: " + file : ": " + file + ": " + std::strerror(errno)));
  expect(!S_ISDIR(st.st_mode), v, name + ": " + file + " is a folder, not a file");
  expect(S_ISREG(st.st_mode), v, name + ": " + file + ": not a regular file (a FIFO, socket or device)");
  return file;
}

// The environment map's file, resolved against the scene's folder.
std::string environment_file(const toml::value& t, const std::string& scene_path) {
  const std::string file = input_file(t.at("environment"), "light.environment", scene_path);
  expect(!t.contains("sky"), t.contains("sky") ? t.at("sky") : t,
         "light.sky: the environment map is the sky; give one of sky and environment");
  return file;
}

LightSpec read_light(const toml::value& t, const std::string& scene_path) {
  check_keys(t, "light.", {"sky", "sun_direction", "sun_radiance", "sun_angle", "environment", "environment_scale"});
  LightSpec l;
  if (t.contains("environment")) l.environment = environment_file(t, scene_path);
  if (t.contains("environment_scale")) {
    expect(t.contains("environment"), t.at("environment_scale"), "light.environment_scale: there is no environment map");
    l.environment_scale = bounded(t, "environment_scale", "light.", 0, 1e9);
  }
  if (t.contains("sky")) l.sky = rgb(t.at("sky"), "light.sky", 0, 1e6);
  if (t.contains("sun_direction")) l.sun_direction = direction(t.at("sun_direction"), "light.sun_direction");
  if (t.contains("sun_radiance")) l.sun = rgb(t.at("sun_radiance"), "light.sun_radiance", 0, 1e9);
  if (t.contains("sun_angle")) l.sun_angle = bounded(t, "sun_angle", "light.", 0.05, 45);
  return l;
}

// `bounds = [[x0, y0, z0], [x1, y1, z1]]`: a box of positive extent.
media::Box read_bounds(const toml::value& v, const std::string& name) {
  expect(v.is_array() && v.as_array().size() == 2, v, name + ": expected [[x0, y0, z0], [x1, y1, z1]]");
  const media::Box b{position(v.as_array()[0], name), position(v.as_array()[1], name)};
  expect(b.lower.x < b.upper.x && b.lower.y < b.upper.y && b.lower.z < b.upper.z, v,
         name + ": inverted or empty: each upper coordinate must exceed its lower one");
  return b;
}

// The medium's density grid, read now: a .vdb, or a .npy with `bounds`.
void read_grid(const toml::value& t, const std::string& where, const std::string& scene_path, MediumSpec& m) {
  m.grid_file = input_file(t.at("grid"), where + "grid", scene_path);
  const bool npy = m.grid_file.size() >= 4 && m.grid_file.compare(m.grid_file.size() - 4, 4, ".npy") == 0;
  std::optional<media::Box> bounds;
  if (t.contains("bounds")) {
    expect(npy, t.at("bounds"), where + "bounds: for a .npy grid only (a .vdb places its voxels itself)");
    bounds = read_bounds(t.at("bounds"), where + "bounds");
  }
  expect(!npy || bounds, t.at("grid"), where + "bounds: a .npy grid needs bounds = [[x0, y0, z0], [x1, y1, z1]]");
  try {
    m.grid = std::make_shared<const media::DensityGrid>(media::DensityGrid::read(m.grid_file, bounds));
  } catch (const std::exception& e) {
    error_at(t.at("grid"), where + "grid: " + e.what());
  }
}

MediumSpec read_medium(const toml::value& t, std::size_t i, const std::string& scene_path) {
  const std::string where = "media[" + std::to_string(i) + "].";
  expect(t.is_table(), t, "media[" + std::to_string(i) + "]: expected a table");
  check_keys(t, where, {"name", "sigma_s", "sigma_a", "g", "preset", "density", "grid", "bounds"});
  MediumSpec m;
  m.name = name_text(require(t, "name", where), where + "name");
  expect(!t.contains("bounds") || t.contains("grid"), t.contains("bounds") ? t.at("bounds") : t,
         where + "bounds: places a grid; there is none");
  if (t.contains("grid")) read_grid(t, where, scene_path, m);
  if (t.contains("preset")) {
    expect(!t.contains("sigma_s") && !t.contains("sigma_a") && !t.contains("g"), t.at("preset"),
           where + "preset: give either a preset or sigma_s, sigma_a and g");
    const std::string name = text(t.at("preset"), where + "preset");
    const MeasuredMedium* p = find_measured_medium(name);
    std::string known;
    for (const MeasuredMedium& k : measured_media()) known += std::string(known.empty() ? "" : ", ") + k.name;
    expect(p != nullptr, t.at("preset"), where + "preset: unknown medium '" + name + "' (known: " + known + ")");
    const double density = t.contains("density") ? bounded(t, "density", where, 1e-9, 1e9) : 1.0;
    for (std::size_t c = 0; c < 3; ++c) m.sigma_s[c] = density * p->sigma_s[c], m.sigma_a[c] = density * p->sigma_a[c];
    m.g = p->g;
    return m;
  }
  expect(!t.contains("density"), t.contains("density") ? t.at("density") : t, where + "density: scales a preset only");
  m.sigma_s = rgb(require(t, "sigma_s", where), where + "sigma_s", 0, 1e7);
  m.sigma_a = rgb(require(t, "sigma_a", where), where + "sigma_a", 0, 1e7);
  m.g = rgb(require(t, "g", where), where + "g", -0.999, 0.999);
  for (int c = 0; c < 3; ++c) expect(m.sigma_t(c) > 0, t, where + "sigma_s, sigma_a: must not both be 0 in a channel");
  return m;
}

// The index of the object's medium in the scene's media.
int object_medium(const toml::value& t, const std::string& where, const RenderScene& s) {
  const std::string medium = text(require(t, "medium", where), where + "medium");
  for (std::size_t k = 0; k < s.media.size(); ++k)
    if (s.media[k].name == medium) return int(k);
  error_at(t.at("medium"), where + "medium: no [[media]] named '" + medium + "'");
}

ObjectSpec read_object(const toml::value& t, std::size_t i, const RenderScene& s) {
  const std::string where = "objects[" + std::to_string(i) + "].", object = "objects[" + std::to_string(i) + "]";
  expect(t.is_table(), t, object + ": expected a table");
  check_keys(t, where, {"mesh", "shape", "radius", "scale", "translate", "medium", "ior"});
  ObjectSpec o;
  o.line = int(t.location().line());
  const int medium = object_medium(t, where, s);
  const MediumSpec& m = s.media[std::size_t(medium)];
  if (m.grid && !t.contains("mesh") && !t.contains("shape")) {  // the grid's box
    o.box = true, o.box_bounds = m.grid->support();
    expect(!t.contains("radius"), t.contains("radius") ? t.at("radius") : t, where + "radius: for shape = \"sphere\" only");
  } else {
    expect(t.contains("mesh") != t.contains("shape"), t,
           object + ": give either mesh = \"FILE.obj\" or shape = \"sphere\"" + (m.grid ? " (or neither: the grid's box)" : ""));
  }
  if (t.contains("mesh")) {
    o.mesh = input_file(t.at("mesh"), where + "mesh", s.path);
    expect(!t.contains("radius"), t.contains("radius") ? t.at("radius") : t, where + "radius: for shape = \"sphere\" only");
  } else if (t.contains("shape")) {
    expect(text(t.at("shape"), where + "shape") == "sphere", t.at("shape"), where + "shape: only \"sphere\" is known");
    if (t.contains("radius")) o.radius = bounded(t, "radius", where, 1e-6, 1e6);
  }
  if (t.contains("scale")) o.scale = bounded(t, "scale", where, 1e-6, 1e6);
  if (t.contains("translate")) o.translate = position(t.at("translate"), where + "translate");
  if (t.contains("ior")) o.ior = bounded(t, "ior", where, 1, 4);
  o.medium = medium;
  return o;
}

GroundSpec read_ground(const toml::value& t) {
  check_keys(t, "ground.", {"height", "albedo"});
  GroundSpec g;
  g.present = true;
  if (t.contains("height")) g.height = bounded(t, "height", "ground.", -1e6, 1e6);
  if (t.contains("albedo")) g.albedo = rgb(t.at("albedo"), "ground.albedo", 0, 1);
  return g;
}

const toml::value& table_at(const toml::value& root, const std::string& key) {
  expect(root.at(key).is_table(), root.at(key), key + ": expected a table");
  return root.at(key);
}

const toml::array& array_at(const toml::value& root, const std::string& key, const std::string& what) {
  if (!root.contains(key) || !root.at(key).is_array() || root.at(key).as_array().empty())
    error_at(root.contains(key) ? root.at(key) : root, key + ": the scene needs at least one [[" + key + "]] table (" + what + ")");
  return root.at(key).as_array();
}

}  // namespace

bool is_render_scene(const std::string& path) { return parse_toml(path).contains("objects"); }

RenderScene read_render_scene(const std::string& path) {
  const toml::value root = parse_toml(path);
  RenderScene s;
  s.path = path;
  check_keys(root, "", {"camera", "light", "media", "objects", "ground"});
  if (root.contains("camera")) s.camera = read_camera(table_at(root, "camera"));
  if (root.contains("light")) s.light = read_light(table_at(root, "light"), path);
  if (root.contains("ground")) s.ground = read_ground(table_at(root, "ground"));
  const auto& media = array_at(root, "media", "name, and sigma_s, sigma_a and g or a preset");
  std::set<std::string> names;
  for (std::size_t i = 0; i < media.size(); ++i) {
    s.media.push_back(read_medium(media[i], i, path));
    expect(names.insert(s.media.back().name).second, media[i], "media[" + std::to_string(i) + "].name: used twice");
  }
  const auto& objects = array_at(root, "objects", "a mesh or shape, and a medium");
  for (std::size_t i = 0; i < objects.size(); ++i) s.objects.push_back(read_object(objects[i], i, s));
  return s;
}

}  // namespace stf::scene
