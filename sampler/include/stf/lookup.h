// Which precomputed sphere to use at a point of a medium at render time.
#pragma once

#include <string>
#include <vector>

#include "stf/pack.h"

namespace stf {

// Among the pack's entries for medium `name` (PackEntry::name), the largest precomputed
// sphere that fits at a point whose distance to the medium's boundary is `free_radius`:
// the entry with the largest tau not above sigma_t * free_radius. Its radius in the scene is
// tau / sigma_t, written to `radius`. nullptr when the point is too close to the boundary for
// any entry (or the medium has none): the renderer then tracks the path directly.
const PackEntry* find_entry(const std::vector<PackEntry>& pack, const std::string& name, double sigma_t,
                            double free_radius, double& radius);

}  // namespace stf
