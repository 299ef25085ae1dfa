#include "stf/lookup.h"

#include <algorithm>

namespace stf {

const PackEntry* find_entry(const std::vector<PackEntry>& pack, double albedo, double g, double sigma_t,
                            double free_radius, double& radius) {
  const double fits = sigma_t * free_radius;
  const PackEntry* best = nullptr;
  // The medium is compared last: this runs once per path vertex, and most entries fail on tau.
  for (const PackEntry& e : pack)
    if (e.model.tau <= fits && (!best || e.model.tau > best->model.tau) && same_medium(e.model, albedo, g)) best = &e;
  radius = best ? best->model.tau / sigma_t : 0;
  return best;
}

SphereLookup::SphereLookup(const std::vector<PackEntry>& pack, double albedo, double g) {
  for (std::size_t i = 0; i < pack.size(); ++i)
    if (same_medium(pack[i].model, albedo, g)) pack_index_.push_back(i);
  const auto tau = [&](std::size_t i) { return pack[i].model.tau; };
  // Of equal taus find_entry keeps the first in pack order: sort stably, keep the first of each.
  std::stable_sort(pack_index_.begin(), pack_index_.end(), [&](std::size_t a, std::size_t b) { return tau(a) < tau(b); });
  pack_index_.erase(std::unique(pack_index_.begin(), pack_index_.end(),
                                [&](std::size_t a, std::size_t b) { return tau(a) == tau(b); }),
                    pack_index_.end());
  for (std::size_t i : pack_index_) {
    taus_.push_back(tau(i));
    samplers_.emplace_back(pack[i].model);
  }
}

int SphereLookup::find(double sigma_t, double free_radius, double& radius) const {
  const double fits = sigma_t * free_radius;
  // taus_ ascends: the count of those that fit is one past the largest. Counting without an
  // early exit has no branch to mispredict, and a pack has a handful of spheres per medium.
  int i = -1;
  for (double tau : taus_) i += tau <= fits;
  radius = i < 0 ? 0 : taus_[std::size_t(i)] / sigma_t;
  return i;
}

}  // namespace stf
