// A render scene (`stf render SCENE.toml`, layout in docs/scenes.md "Render scenes"): a pinhole
// camera, a sky (or an environment map) and a sun, media in RGB, objects (closed OBJ meshes or analytic spheres) each
// filled with one medium behind an index-matched or smooth dielectric boundary, and an
// optional diffuse ground plane.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "stf/media/density_grid.h"
#include "stf/scene/presets.h"
#include "stf/vec3.h"

namespace stf::scene {

// The largest coordinate a scene may place a point at (camera, translations, mesh vertices after
// placement): Embree traces meshes in float (at 1e9 its spacing is 64 units) and drops bounds
// beyond about 1.8e18 altogether, so that a mesh there would vanish from the image.
inline constexpr double kLargestCoordinate = 1e9;

struct CameraSpec {
  Vec3 position{0, 0, 3}, look_at{0, 0, 0}, up{0, 1, 0};  // up: unit after reading
  double fov = 30;  // vertical, degrees
  int width = 256, height = 256;
};

struct LightSpec {
  Rgb sky{1, 1, 1};           // uniform radiance from every direction
  Vec3 sun_direction = normalize(Vec3{1, 1, -1});  // towards the sun, unit
  Rgb sun{50, 50, 50};        // radiance within the sun's disc, added to the sky's
  double sun_angle = 5;       // half-angle of the disc, degrees
  // A latitude-longitude map in place of the sky (docs/scenes.md, "Render scene"), resolved against
  // the scene's folder, and its scale; "" for none.
  std::string environment;
  double environment_scale = 1;
};

struct MediumSpec {
  std::string name;
  Rgb sigma_s{}, sigma_a{}, g{};  // per scene unit; per unit density too where the medium has a grid
  double sigma_t(int c) const { return sigma_s[std::size_t(c)] + sigma_a[std::size_t(c)]; }
  // The density grid (`grid = "FILE"`, read with the scene), in the frame of each object filled
  // with the medium; null for a homogeneous medium.
  std::string grid_file;
  std::shared_ptr<const media::DensityGrid> grid;
};

struct ObjectSpec {
  std::string mesh;       // path of an OBJ file (resolved against the scene's folder), or ""
  double radius = 1;      // the analytic sphere's, when mesh is "" and box is false
  // No mesh or shape, a medium with a grid: the object is the box of the grid's support (in its
  // frame, before scale and translate).
  bool box = false;
  media::Box box_bounds;
  double scale = 1;
  Vec3 translate;
  int medium = 0;         // index into RenderScene::media
  double ior = 1;         // 1: index matched; above: a smooth dielectric
  int line = 0;           // where the object is in the file, for messages
};

struct GroundSpec {
  bool present = false;
  double height = 0;  // the plane y = height
  Rgb albedo{0.5, 0.5, 0.5};
};

struct RenderScene {
  std::string path;
  CameraSpec camera;
  LightSpec light;
  std::vector<MediumSpec> media;
  std::vector<ObjectSpec> objects;
  GroundSpec ground;
};

// Whether the TOML file at `path` is a render scene (it has [[objects]]) rather than a pack
// recipe (stf/scene/scene.h); throws SceneError where it is no TOML that stf reads.
bool is_render_scene(const std::string& path);

// Reads and checks a render scene and its media's grids; throws SceneError "file:line: key: why"
// (unknown keys, values of the wrong type or range, unknown presets or media, missing mesh files,
// grids that cannot be read).
RenderScene read_render_scene(const std::string& path);

}  // namespace stf::scene
