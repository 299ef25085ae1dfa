// The straightforward walk the fast kernel is measured against: one path at a time, double
// precision, std::log / std::sin / std::cos, the textbook HG inversion. Same physics and
// binning as precompute/walk.cpp.
#pragma once

#include <cstdint>

#include "stf/precompute/walk.h"

namespace stf::bench {

void baseline_walk(const WalkSetup& setup, std::uint64_t seed, std::int64_t paths, Tally& tally);

}  // namespace stf::bench
