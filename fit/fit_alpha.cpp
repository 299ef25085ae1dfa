// The alpha stage (fit_stages.h): the smoothed alpha marginal, the tilts, and the turns taken
// from the slopes of the bins' headings smoothed across alpha (fit_table.h).
#include "fit_stages.h"
#include "stf/vec3.h"

namespace stf::fit {

std::vector<double> smooth_headings(std::vector<double> headings, const std::vector<double>& escapes,
                                    std::vector<double>* slopes) {
  std::vector<double>& h = headings;
  // Each against the last bin with escapes: an empty bin's heading (atan2(0, 0) = 0) is none.
  for (std::size_t b = 0, last = 0, seen = 0; b < h.size(); ++b) {
    if (seen) h[b] -= 2 * kPi * std::round((h[b] - h[last]) / (2 * kPi));
    if (escapes[b] > 0) last = b, seen = 1;
  }
  const int bins = int(h.size());
  std::vector<double> smooth = h;
  if (slopes) slopes->assign(h.size(), 0.0);
  for (int b = 0; b < bins; ++b) {
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d right = Eigen::Vector3d::Zero();
    for (int j = std::max(0, b - kConfig.heading_window); j <= std::min(bins - 1, b + kConfig.heading_window); ++j) {
      const double d = j - b, w = escapes[std::size_t(j)] * (1 - std::abs(d) / (kConfig.heading_window + 1));
      const Eigen::Vector3d x(1, d, d * d);
      normal += w * x * x.transpose(), right += w * x * h[std::size_t(j)];
    }
    const Eigen::FullPivLU<Eigen::Matrix3d> lu(normal);
    if (lu.rank() < 3) continue;
    const Eigen::Vector3d fit = lu.solve(right);
    smooth[std::size_t(b)] = fit(0);
    if (slopes) (*slopes)[std::size_t(b)] = fit(1);
  }
  return smooth;
}

std::vector<double> alpha_turns(const std::vector<double>& headings, const std::vector<double>& escapes,
                                const std::vector<double>& alpha_edges) {
  std::vector<double> slopes;
  smooth_headings(headings, escapes, &slopes);
  std::vector<double> turn(headings.size());
  for (std::size_t b = 0; b < turn.size(); ++b)
    turn[b] = std::clamp(slopes[b] / (alpha_edges[b + 1] - alpha_edges[b]), -kConfig.max_fitted_turn, kConfig.max_fitted_turn);
  return turn;
}

namespace stages {

AlphaShape alpha_shape(Escapes& e, const FitSettings& s) {
  const Table& t = e.table;
  AlphaShape a;
  if (s.smooth_alpha) a.marginal = smooth_alpha_marginal(t);
  a.tilts = !s.tilt                        ? std::vector<double>(std::size_t(t.alpha_bins), 0.0)
            : a.marginal.sub_escapes.empty() ? fit_alpha_tilts(t)
                                             : tilts_from_sub_counts(t, a.marginal.sub_escapes);
  if (s.kind == ModelKind::kVmf && s.turn && t.alpha_bins > 1) e.set_turns(a.tilts);
  return a;
}

}  // namespace stages

}  // namespace stf::fit
