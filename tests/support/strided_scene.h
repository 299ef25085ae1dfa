// The medium and mesh the test pack (tests/cli/render_scene.toml: spheres of tau 2 and 4 at
// albedo 0.99 and g 0.5) strides through: three channels of sigma_t 8, 4 and 16, so that its
// spheres serve all three at different radii, in an icosphere of radius 0.8 on a grey ground.
// A scene is a [camera] and a [light] table before it.
#pragma once

#include <string>

namespace stf::test {

inline std::string strided_objects() {
  return R"([[media]]
name = "grey"
sigma_s = [7.92, 3.96, 15.84]
sigma_a = [0.08, 0.04, 0.16]
g = 0.5
[[objects]]
mesh = ")" + std::string(STF_SOURCE_DIR) + R"(/data/scenes/meshes/icosphere.obj"
scale = 1.6
medium = "grey"
[ground]
height = -0.9
albedo = 0.5
)";
}

}  // namespace stf::test
