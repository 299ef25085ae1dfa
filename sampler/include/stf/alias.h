// Walker's alias table: a discrete distribution sampled in O(1) with one comparison, the
// random number's unused fraction handed back for reuse.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace stf {

class AliasTable {
 public:
  AliasTable() = default;
  // weights >= 0 with a positive sum.
  explicit AliasTable(const std::vector<double>& weights);
  // Index i with probability weights[i] / sum; `remainder` in [0, 1) is independent of i.
  int sample(double u, double& remainder) const;
  int size() const { return int(entries_.size()); }

 private:
  struct Entry {
    double threshold;  // keep this index when the fraction is below it
    std::int32_t alias;
  };
  std::vector<Entry> entries_;
};

inline int AliasTable::sample(double u, double& remainder) const {
  const double x = u * double(entries_.size());
  const int i = std::min(int(x), int(entries_.size()) - 1);
  const double f = x - i;
  const Entry& e = entries_[i];
  if (f < e.threshold) {
    remainder = std::min(f / e.threshold, std::nextafter(1.0, 0.0));
    return i;
  }
  remainder = std::min((f - e.threshold) / (1 - e.threshold), std::nextafter(1.0, 0.0));
  return e.alias;
}

}  // namespace stf
