// Which precomputed sphere to use at a point of a medium at render time.
#pragma once

#include <string>
#include <vector>

#include "stf/pack.h"
#include "stf/sampler.h"
#include "stf/stride.h"

namespace stf {

// Among the pack's entries for the medium (albedo, g) (same_medium), the largest precomputed
// sphere that fits at a point whose distance to the medium's boundary is `free_radius`:
// the entry with the largest tau not above sigma_t * free_radius. Its radius in the scene is
// tau / sigma_t, written to `radius`. nullptr when the point is too close to the boundary for
// any entry (or the medium has none): the renderer then tracks the path directly.
const PackEntry* find_entry(const std::vector<PackEntry>& pack, double albedo, double g, double sigma_t,
                            double free_radius, double& radius);

// find_entry for a renderer's inner loop, where it runs at every path vertex: the spheres of
// one medium (albedo, g) sorted by tau once, each with its own sampler (a copy of the model, and its stride
// form, stf/stride.h), so a lookup compares doubles only. Finds the same entries as find_entry; needs nothing of the pack once
// built. Const and thread-safe.
class SphereLookup {
 public:
  SphereLookup(const std::vector<PackEntry>& pack, double albedo, double g);
  // The largest sphere with tau <= sigma_t * free_radius (its radius tau / sigma_t written to
  // `radius`), or -1 when none fits.
  int find(double sigma_t, double free_radius, double& radius) const;
  int size() const { return int(taus_.size()); }
  double tau(int i) const { return taus_[std::size_t(i)]; }  // ascending in i
  const ShellSampler& sampler(int i) const { return samplers_[std::size_t(i)]; }
  const StrideForm& stride_form(int i) const { return samplers_[std::size_t(i)].stride_form(); }
  // Where sphere i is in the pack the lookup was built from.
  std::size_t pack_index(int i) const { return pack_index_[std::size_t(i)]; }

 private:
  std::vector<double> taus_;  // ascending; the samplers' taus, packed together for find()
  std::vector<std::size_t> pack_index_;
  std::vector<ShellSampler> samplers_;
};

}  // namespace stf
