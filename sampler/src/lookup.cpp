#include "stf/lookup.h"

namespace stf {

const PackEntry* find_entry(const std::vector<PackEntry>& pack, const std::string& name, double sigma_t,
                            double free_radius, double& radius) {
  const double fits = sigma_t * free_radius;
  const PackEntry* best = nullptr;
  for (const PackEntry& e : pack)
    if (e.name == name && e.model.tau <= fits && (!best || e.model.tau > best->model.tau)) best = &e;
  radius = best ? best->model.tau / sigma_t : 0;
  return best;
}

}  // namespace stf
