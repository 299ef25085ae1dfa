#include "stf/alias.h"

#include <algorithm>
#include <cmath>

namespace stf {

AliasTable::AliasTable(const std::vector<double>& weights) : entries_(weights.size()) {
  const std::size_t n = weights.size();
  double total = 0;
  for (double w : weights) total += w;
  std::vector<double> scaled(n);
  std::vector<std::int32_t> small, large;
  for (std::size_t i = 0; i < n; ++i) {
    scaled[i] = weights[i] / total * double(n);
    (scaled[i] < 1 ? small : large).push_back(std::int32_t(i));
  }
  // Vose's method: pair each under-full entry with an over-full one.
  while (!small.empty() && !large.empty()) {
    std::int32_t s = small.back(), l = large.back();
    small.pop_back();
    entries_[s] = {scaled[s], l};
    scaled[l] -= 1 - scaled[s];
    if (scaled[l] < 1) {
      large.pop_back();
      small.push_back(l);
    }
  }
  // What is left is full up to rounding.
  for (std::int32_t i : large) entries_[i] = {1.0, i};
  for (std::int32_t i : small) entries_[i] = {weights[i] > 0 ? 1.0 : 0.0, i};
}

}  // namespace stf
