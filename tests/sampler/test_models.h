// Small hand-made models for the sampler tests: a vMF model and an SH model over a few alpha
// bins, with every kind of lobe the sampler must handle.
#pragma once

#include <cmath>

#include "stf/model.h"
#include "stf/sh.h"

namespace stf::test {

inline StfModel make_vmf_model() {
  StfModel m;
  m.kind = ModelKind::kVmf;
  m.tau = 3, m.albedo = 0.9, m.g = 0.4, m.escape_probability = 0.7;
  m.lobes = 3;
  const int bins = 6;
  for (int b = 0; b <= bins; ++b) m.alpha_edges.push_back(kPi * b / bins);
  m.alpha_probability = {0.3, 0.25, 0.2, 0.0, 0.15, 0.1};  // bin 3 is empty
  m.status.assign(bins, BinStatus::kFitted);
  for (int b = 0; b < bins; ++b) {
    double a = 0.5 * (m.alpha_edges[b] + m.alpha_edges[b + 1]);
    m.vmf.push_back({0.6, 5.0 + b, normalize({std::sin(a), 0, std::cos(a)})});
    m.vmf.push_back({0.3, 80, normalize({std::sin(a), 0.2, std::cos(a) + 0.3})});
    m.vmf.push_back({0.1, 0.0, {0, 0, 1}});  // a uniform lobe
  }
  return m;
}

inline StfModel make_sh_model() {
  StfModel m;
  m.kind = ModelKind::kSh;
  m.tau = 1, m.albedo = 0.5, m.g = -0.2, m.escape_probability = 0.4;
  m.band_limit = 4;
  m.sh_nz = 16;
  const int bins = 4, count = sh_count(m.band_limit);
  for (int b = 0; b <= bins; ++b) m.alpha_edges.push_back(kPi * b / bins);
  m.alpha_probability = {0.4, 0.3, 0.2, 0.1};
  m.status.assign(bins, BinStatus::kFitted);
  for (int b = 0; b < bins; ++b) {
    std::vector<double> c(count, 0.0);
    c[0] = 1 / std::sqrt(4 * kPi);
    c[2] = 0.25 + 0.05 * b;  // l = 1, m = 0: towards +z
    c[3] = 0.15;             // l = 1, m = 1: towards +x
    c[6] = 0.3;              // l = 2, m = 0: strong enough to clamp somewhere
    m.sh.insert(m.sh.end(), c.begin(), c.end());
  }
  m.rebuild_sh_tables();
  return m;
}

// A model whose bin 0 also holds an uncollided delta (40% of that bin).
inline StfModel with_uncollided(StfModel m) {
  m.uncollided_fraction = 0.4 * m.alpha_probability[0];
  return m;
}

// Exit points crowding to either edge of their bins (stf/tilt.h), strongly in some.
inline StfModel tilted(StfModel m) {
  const double tilts[] = {-2.5, 1.0, 0.3, 0.0, -0.7, 4.0};
  for (int b = 0; b < m.bins(); ++b) m.alpha_tilt.push_back(tilts[b % 6]);
  return m;
}

// Bins blended with their neighbours over `width` bins (StfModel::alpha_blend).
inline StfModel blended(StfModel m, int width = 1) {
  m.alpha_blend = width;
  return m;
}

// Bins blended over widths of their own (StfModel::alpha_blend_width); unblended bins next to
// bins of the widest, whose hats reach into them.
inline StfModel blended_by_bin(StfModel m) {
  const int widths[] = {0, 3, 1, 2, 3, 0};
  for (int b = 0; b < m.bins(); ++b) m.alpha_blend_width.push_back(widths[b % 6]);
  m.alpha_blend = 3;
  return m;
}

// Densities that turn about y with the exit angle inside their bins (StfModel::alpha_turn), some
// against the exit point, one by 90 degrees across its bin.
inline StfModel turned(StfModel m) {
  const double rates[] = {1.5, -2.0, 3.0, 0.7, 1.0, -0.5};
  for (int b = 0; b < m.bins(); ++b) m.alpha_turn.push_back(rates[b % 6]);
  return m;
}

// The same lobes made hemispherical: each times its bin's outward cosine, renormalised.
inline StfModel hemispherical(StfModel m) {
  m.hemispherical = true;
  m.rebuild_lobe_norms();
  return m;
}

// The same lobes lifted to each exit point's outward hemisphere (StfModel::lifted).
inline StfModel lifted(StfModel m) {
  m.lifted = true;
  return m;
}

}  // namespace stf::test
