// Blend widths from held-out scores of turned neighbours (fit_stages.h).
#include "fit_stages.h"

namespace stf::fit::stages {

TurnedNeighbours turned_neighbours(const BinFits& fits, const std::vector<BinTurn>& turns, const QuadratureLevels& levels,
                                   int width, const FitSettings& s) {
  const Table& t = *fits.table;
  const std::vector<double>& edges = t.alpha_edges;
  auto middle = [&](int bin) { return 0.5 * (edges[std::size_t(bin)] + edges[std::size_t(bin) + 1]); };
  TurnedNeighbours n{width, std::vector<std::vector<std::vector<double>>>(
                                std::size_t(t.alpha_bins), std::vector<std::vector<double>>(2 * std::size_t(width) + 1))};
  for_each_bin(t.alpha_bins, s, "blends", [&](int b) {
    for (int j = std::max(0, b - width); j <= std::min(t.alpha_bins - 1, b + width); ++j) {
      if (j == b) continue;
      const double angle = turns[std::size_t(j)].rate * (middle(b) - middle(j));
      std::vector<VmfLobe> lobes = fits.lobes[std::size_t(j)];
      for (VmfLobe& l : lobes) l.mean = turn_about_y(l.mean, angle);
      // Lifted lobes are mapped about the normals of bin b's exit points, where it draws them.
      const BinTurn moved = fits.lifted ? BinTurn{0, edges[std::size_t(b)], edges[std::size_t(b) + 1], 0, true}
                                        : BinTurn{0, edges[std::size_t(j)] + angle, edges[std::size_t(j) + 1] + angle, 0};
      n.cells[std::size_t(b)][std::size_t(j - b + width)] =
          lobe_cells(fits, lobes, levels, both_halves(t, j), moved, Tails::kCut);
    }
  });
  return n;
}

std::vector<int> widths_by_bin(const std::vector<HeldOut>& blended) {
  const int bins = int(blended[0].bin_nll.size());
  std::vector<int> widths(std::size_t(bins), 0);
  for (int b = 0; b < bins; ++b) {
    double best = 0;
    for (std::size_t w = 1; w < blended.size(); ++w) {
      double gain = 0;
      for (int j = std::max(0, b - kConfig.blend_reach); j <= std::min(bins - 1, b + kConfig.blend_reach); ++j)
        gain += (1 - double(std::abs(j - b)) / (kConfig.blend_reach + 1)) *
                (blended[0].bin_nll[std::size_t(j)] - blended[w].bin_nll[std::size_t(j)]);
      if (gain > best) best = gain, widths[std::size_t(b)] = int(w);
    }
  }
  return widths;
}

HeldOut scores_at_widths(const std::vector<HeldOut>& blended, const std::vector<int>& widths) {
  HeldOut h;
  for (std::size_t b = 0; b < widths.size(); ++b) {
    const HeldOut& at = blended[std::size_t(widths[b])];
    h.bin_nll.push_back(at.bin_nll[b]);
    h.nll += at.bin_nll[b];
    h.log_p.push_back(at.log_p[b]);
  }
  return h;
}

std::vector<int> choose_blend(const Escapes& e, const HeldOut& flat, const FitSettings& s, const TurnedNeighbours& turned,
                              FitReport& r) {
  const Table& t = e.table;
  StfModel shape;
  shape.alpha_probability.assign(std::size_t(t.alpha_bins), 0.0);
  shape.alpha_tilt = fit_alpha_tilts(t, 0);
  std::vector<std::vector<double>> p(t.alpha_bins), q(t.alpha_bins);
  for (int b = 0; b < t.alpha_bins; ++b)
    for (double l : flat.log_p[b]) p[b].push_back(std::exp(l));
  std::vector<double>& nll = r.blend_heldout_nll = {flat.nll};
  std::vector<double>& error = r.blend_heldout_nll_error = {0.0};
  std::vector<HeldOut> blended{flat};
  for (shape.alpha_blend = 1; shape.alpha_blend <= s.max_blend; ++shape.alpha_blend) {
    for (int b = 0; b < t.alpha_bins; ++b)
      q[b] = blended_cells(shape, b, [&](int j) -> const std::vector<double>& {
        return j == b || turned.cells.empty() ? p[std::size_t(j)] : turned.at(j, b);
      });
    blended.push_back(score(e, 1, q));
    nll.push_back(blended.back().nll);
    error.push_back(difference_error(e, 1, blended.back(), flat));
  }
  int& width = r.blend_width = 0;
  for (int w = 1; w <= s.max_blend; ++w)
    if (nll[std::size_t(w)] < nll[std::size_t(width)] && nll[0] - nll[std::size_t(w)] > kConfig.blend_standard_errors * error[std::size_t(w)])
      width = w;
  const std::vector<int> one(std::size_t(t.alpha_bins), width), by_bin = widths_by_bin(blended);
  const HeldOut at_one = scores_at_widths(blended, one), at_by_bin = scores_at_widths(blended, by_bin);
  r.blend_by_bin_gain = at_one.nll - at_by_bin.nll;
  r.blend_by_bin_error = difference_error(e, 1, at_by_bin, at_one);
  const bool keep_by_bin = s.blend_by_bin && r.blend_by_bin_gain > kConfig.blend_standard_errors * r.blend_by_bin_error;
  const std::vector<int>& widths = keep_by_bin ? by_bin : one;
  return std::any_of(widths.begin(), widths.end(), [](int h) { return h > 0; }) ? widths : std::vector<int>{};
}

}  // namespace stf::fit::stages
