// An axis-aligned box: a grid's bounds, its support, in the grid's frame or on its lattice.
#pragma once

#include "stf/vec3.h"

namespace stf::media {

struct Box {
  Vec3 lower, upper;
};

}  // namespace stf::media
