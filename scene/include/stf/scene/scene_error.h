// The one error of stf's TOML files (scenes and render scenes).
#pragma once

#include <stdexcept>

namespace stf::scene {

// A bad scene file: the message names the file, the line and the key.
struct SceneError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace stf::scene
