#include "lattice.h"

#include <cmath>
#include <sstream>

namespace stf::media {

std::string name_index(const Lattice& lattice, std::size_t flat) {
  const auto& n = lattice.dims;
  const std::int64_t k = std::int64_t(flat) % n[2], j = std::int64_t(flat) / n[2] % n[1], i = std::int64_t(flat) / n[2] / n[1];
  const auto& o = lattice.index_origin;
  std::ostringstream text;
  if (lattice.vdb_index)
    text << "index (" << i + o[0] << ", " << j + o[1] << ", " << k + o[2] << ")";
  else
    text << "[" << i << ", " << j << ", " << k << "]";
  return text.str();
}

void check_values(const Lattice& lattice) {
  for (std::size_t flat = 0; flat < lattice.values.size(); ++flat) {
    const float v = lattice.values[flat];
    if (std::isfinite(v) && v >= 0) continue;
    std::ostringstream what;
    what << (std::isfinite(v) ? "negative" : "non-finite") << " density " << v << " at " << name_index(lattice, flat)
         << " (densities are finite and non-negative)";
    throw grid_error(lattice.source, what.str());
  }
}

void check_bounds(const std::string& source, const Box& bounds) {
  const double lower[3] = {bounds.lower.x, bounds.lower.y, bounds.lower.z};
  const double upper[3] = {bounds.upper.x, bounds.upper.y, bounds.upper.z};
  for (int a = 0; a < 3; ++a) {
    std::ostringstream what;
    what << "bounds on " << "xyz"[a] << " are [" << lower[a] << ", " << upper[a] << "]";
    if (!std::isfinite(lower[a]) || !std::isfinite(upper[a]))
      throw grid_error(source, what.str() + ": not finite");
    if (!(lower[a] < upper[a]))
      throw grid_error(source, what.str() + ": the lower bound must be below the upper");
  }
}

void place_in_bounds(Lattice& lattice, const Box& bounds) {
  const double lower[3] = {bounds.lower.x, bounds.lower.y, bounds.lower.z};
  const double upper[3] = {bounds.upper.x, bounds.upper.y, bounds.upper.z};
  for (int a = 0; a < 3; ++a) {
    const double voxel = (upper[a] - lower[a]) / double(lattice.dims[a]);
    lattice.to_world[a] = {0, 0, 0, lower[a] + voxel / 2};  // lattice point 0 at the first voxel's centre
    lattice.to_world[a][std::size_t(a)] = voxel;
  }
  const auto& n = lattice.dims;
  lattice.clip = {{-0.5, -0.5, -0.5}, {double(n[0]) - 0.5, double(n[1]) - 0.5, double(n[2]) - 0.5}};
}

}  // namespace stf::media
