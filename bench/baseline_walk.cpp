#include "baseline_walk.h"

#include <algorithm>
#include <cmath>

#include "stf/core/geometry.h"
#include "stf/core/rng.h"

namespace stf::bench {

namespace {

double uniform(std::uint64_t& state) { return double(splitmix64(state) >> 11) * 0x1p-53; }

double sample_hg_textbook(double g, double xi) {
  if (std::abs(g) < 1e-3) return 1 - 2 * xi;
  double s = (1 - g * g) / (1 - g + 2 * g * xi);
  return (1 + g * g - s * s) / (2 * g);
}

}  // namespace

void baseline_walk(const WalkSetup& setup, std::uint64_t seed, std::int64_t paths, Tally& tally) {
  std::uint64_t state = seed;
  for (std::int64_t path = 0; path < paths; ++path) {
    Vec3 p{0, 0, 0}, w{0, 0, 1};
    std::int64_t n = 0;
    for (;;) {
      double flight = -std::log(1 - uniform(state)) / setup.tau;
      double b = dot(p, w), c = dot(p, p) - 1;
      double root = std::sqrt(std::max(b * b - c, 0.0));
      double to_exit = b > 0 ? -c / (b + root) : root - b;
      if (flight >= to_exit) {
        p = {p.x + to_exit * w.x, p.y + to_exit * w.y, p.z + to_exit * w.z};
        ReducedExit exit = reduce_exit(normalize(p), w);
        int bin = std::min(int(exit.alpha / kPi * setup.alpha_bins), setup.alpha_bins - 1);
        ++tally.counts[path & 1][std::size_t(bin) * tally.cells + setup.grid->cell(exit.direction)];
        ++tally.escaped;
        break;
      }
      p = {p.x + flight * w.x, p.y + flight * w.y, p.z + flight * w.z};
      if (++n > setup.max_scatter) {
        ++tally.truncated;
        break;
      }
      if (uniform(state) >= setup.albedo) {
        ++tally.absorbed;
        break;
      }
      double mu = sample_hg_textbook(setup.g, uniform(state));
      double st = std::sqrt(std::max(0.0, 1 - mu * mu));
      double phi = 2 * kPi * uniform(state);
      double cp = std::cos(phi), sp = std::sin(phi);
      double sign = std::copysign(1.0, w.z), a = -1 / (sign + w.z), bb = w.x * w.y * a;
      Vec3 e1{1 + sign * w.x * w.x * a, sign * bb, -sign * w.x}, e2{bb, sign + w.y * w.y * a, -w.y};
      w = normalize({st * (cp * e1.x + sp * e2.x) + mu * w.x, st * (cp * e1.y + sp * e2.y) + mu * w.y,
                     st * (cp * e1.z + sp * e2.z) + mu * w.z});
    }
    tally.collisions += std::uint64_t(n);
  }
}

}  // namespace stf::bench
