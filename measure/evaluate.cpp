#include "stf/measure/evaluate.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>

#include "stf/fit/alpha_tilt.h"
#include "stf/fit/cell_integral.h"
#include "stf/core/grid.h"
#include "stf/tilt.h"

namespace stf::measure {

using namespace stf::fit;  // the fit this measures: its models, cell integrals and settings

namespace {

std::vector<double> bin_distribution(const Table& t, int b, double& total) {
  std::vector<double> p(t.cells);
  total = 0;
  for (std::int64_t c = 0; c < t.cells; ++c) {
    std::size_t i = std::size_t(b) * t.cells + c;
    total += (p[c] = t.weight_half[0][i] + t.weight_half[1][i]);
  }
  if (total > 0)
    for (double& v : p) v /= total;
  return p;
}

BinError compare(const std::vector<double>& p, const std::vector<double>& q) {
  BinError e;
  for (std::size_t c = 0; c < q.size(); ++c) {
    e.tv += 0.5 * std::abs(p[c] - q[c]);
    if (q[c] > 0) e.kl += p[c] > 0 ? q[c] * std::log(q[c] / p[c]) : std::numeric_limits<double>::infinity();
  }
  return e;
}

// Weighted totals over bins by the reference's alpha marginal; `candidate(b)` gives the
// candidate's probability of reference bin b and its cell distribution there. `joint`, when
// given, receives the candidate's joint (bin, cell) probabilities.
template <typename CandidateBin>
Evaluation evaluate_bins(const Table& reference, CandidateBin candidate, std::vector<double>* joint) {
  if (joint) joint->assign(std::size_t(reference.alpha_bins) * std::size_t(reference.cells), 0.0);
  Evaluation ev;
  std::vector<double> mass(reference.alpha_bins);
  std::vector<std::vector<double>> q(reference.alpha_bins);
  double total = 0;
  for (int b = 0; b < reference.alpha_bins; ++b) {
    q[b] = bin_distribution(reference, b, mass[b]);
    total += mass[b];
  }
  for (int b = 0; b < reference.alpha_bins; ++b) {
    auto [probability, p] = candidate(b);
    BinError e = mass[b] > 0 ? compare(p, q[b]) : BinError{};
    e.weight = total > 0 ? mass[b] / total : 0;
    for (std::size_t c = 0; c < p.size(); ++c) ev.joint_tv += 0.5 * std::abs(probability * p[c] - e.weight * q[b][c]);
    if (joint)
      for (std::size_t c = 0; c < p.size(); ++c) (*joint)[std::size_t(b) * p.size() + c] = probability * p[c];
    ev.per_alpha.push_back(e);
    if (e.weight == 0) continue;
    ev.tv += e.weight * e.tv;
    ev.kl += e.weight * e.kl;
  }
  return ev;
}

}  // namespace

int alpha_group_size(const std::vector<double>& edges, const Table& reference) {
  const int bins = int(edges.size()) - 1;
  if (bins < 1 || reference.alpha_bins % bins != 0)
    throw std::invalid_argument("alpha bins (" + std::to_string(bins) + ") are neither the reference's (" +
                                std::to_string(reference.alpha_bins) + ") nor groups of them");
  const int f = reference.alpha_bins / bins;
  for (int j = 0; j <= bins; ++j)
    if (std::abs(edges[j] - reference.alpha_edges[std::size_t(j) * f]) > 1e-12)
      throw std::invalid_argument("alpha bin edges are not edges of the reference's");
  return f;
}

std::vector<double> smooth_cell_probabilities(const StfModel& m, int b, const QuadratureLevels& levels, double turn,
                                              double exit_a0, double exit_a1) {
  if (m.kind == ModelKind::kVmf) {
    std::vector<VmfLobe> lobes(m.lobes_of(b).begin(), m.lobes_of(b).end());
    for (VmfLobe& l : lobes) l.mean = turn_about_y(l.mean, turn);
    if (m.lifted) {  // mapped about each exit point's own normal, over the exit angles asked for
      const bool own = exit_a0 == 0 && exit_a1 == 0;
      const fit::BinTurn exits{0, own ? m.alpha_edges[std::size_t(b)] : exit_a0, own ? m.alpha_edges[std::size_t(b) + 1] : exit_a1,
                               0, true};
      return lobe_cell_probabilities(lobes, levels, 1e8, nullptr, &exits);
    }
    // The quadrature levels the fitter used for lobes this narrow; hemispherical lobes with the
    // outward factor's means over sub-cells, so that cells the tangent planes cut keep their share.
    // The bin's factor turned by `turn` is the factor of the bin's edges moved by it.
    if (!m.hemispherical) return lobe_cell_probabilities(lobes, levels);
    const OutwardFactors outward =
        outward_cell_means(levels, m.alpha_edges[std::size_t(b)] + turn, m.alpha_edges[std::size_t(b) + 1] + turn);
    return lobe_cell_probabilities(lobes, levels, 1e8, &outward);
  }
  return density_cell_probabilities([&](const Vec3& w) { return m.direction_pdf(b, turn_about_y(w, -turn)); },
                                    levels.at(kShMeasureLevel));
}

BinnedModel::BinnedModel(const StfModel& model, const Table& reference, const DirectionGrid& grid)
    : model_(model), reference_(reference), group_(alpha_group_size(model.alpha_edges, reference)),
      pole_cell_(grid.cell({0, 0, 1})) {
  if (model.once_fraction > 0) once_ = bin_once_scattered(model.tau, model.g, reference.alpha_edges, grid);
}

const std::vector<double>& SmoothCellCache::operator()(int j, double turn, double exit_a0, double exit_a1) {
  if (!model_.lifted) exit_a0 = exit_a1 = 0;  // the same cells at every exit angle
  for (const Kept& k : kept_)
    if (k.bin == j && k.turn == turn && k.exit_a0 == exit_a0 && k.exit_a1 == exit_a1) return k.cells;
  // A reference bin needs its model bin and the 2 alpha_blend bins around it (turning models
  // need each at several turns, and keep none for long).
  if (kept_.size() >= std::size_t(2 * model_.alpha_blend + 1)) kept_.erase(kept_.begin());
  kept_.push_back({j, turn, exit_a0, exit_a1, smooth_cell_probabilities(model_, j, levels_, turn, exit_a0, exit_a1)});
  return kept_.back().cells;
}

namespace {
// The widest step of turn between the exit-angle slices a turning model's reference bin is cut
// into: each slice takes the turns at its middle, and a lobe 3 degrees wide (kappa ~ 400) then
// errs by about (step / width)^2 / 24 ~ 1% of its curvature (0.01 rad is 0.57 degrees).
constexpr double kTurnStep = 0.01;

// How many slices of exit angle a reference bin of width `width` needs in model bin j's
// group: enough that no bin blended into it turns by more than kTurnStep within a slice.
int turn_slices(const StfModel& m, int j, double width) {
  if (m.alpha_turn.empty()) return 1;
  double fastest = 0;
  for (int i = std::max(0, j - m.alpha_blend); i <= std::min(m.bins() - 1, j + m.alpha_blend); ++i)
    fastest = std::max(fastest, std::abs(m.alpha_turn[std::size_t(i)]));
  return std::max(1, int(std::ceil(fastest * width / kTurnStep)));
}
}  // namespace

std::pair<double, std::vector<double>> BinnedModel::bin(int b, const SmoothCells& smooth_cells) const {
  const double once = model_.once_fraction;
  // The smooth part is spread over the reference bins of its group by its tilted density in
  // area, as the sampler spreads alpha; the delta sits at alpha = 0, in reference bin 0 alone.
  const int j = b / group_;
  double below = 0;
  for (int a = j * group_; a < b; ++a) below += area_share(reference_, a, group_);
  const double above = std::min(1.0, below + area_share(reference_, b, group_));
  const double smooth = model_.smooth_probability(j);
  std::vector<double> p(reference_.cells, 0.0);
  double smooth_mass = 0;
  // A turning model's densities turn with the exit angle: the bin is cut into slices of equal
  // area, each taking its blended bins' turns at its middle (midpoint rule in the turn).
  const double a0 = reference_.alpha_edges[std::size_t(b)], a1 = reference_.alpha_edges[std::size_t(b) + 1];
  const int slices = turn_slices(model_, j, a1 - a0);
  const double c0 = std::cos(model_.alpha_edges[std::size_t(j)]), c1 = std::cos(model_.alpha_edges[std::size_t(j) + 1]);
  for (int s = 0; s < slices; ++s) {
    const double lo = below + (above - below) * s / slices, hi = below + (above - below) * (s + 1) / slices;
    auto angle = [&](double u) { return std::acos(std::clamp(c0 + u * (c1 - c0), -1.0, 1.0)); };
    const double alpha = angle(0.5 * (lo + hi));
    for (const auto& [bin, share] : blend_shares(model_, j, lo, hi)) {
      smooth_mass += smooth * share;
      if (share <= 0) continue;
      const std::vector<double>& cells = smooth_cells(bin, model_.turn_angle(bin, alpha), angle(lo), angle(hi));
      for (std::size_t c = 0; c < p.size(); ++c) p[c] += smooth * share * cells[c];
    }
  }
  double probability = smooth_mass;
  if (b == 0) {
    p[std::size_t(pole_cell_)] += model_.uncollided_probability();
    probability += model_.uncollided_probability();
  }
  if (once > 0) {
    for (const auto& [c, share] : once_.cells[std::size_t(b)]) p[std::size_t(c)] += once * share;
    probability += once * once_.bin_mass[std::size_t(b)];
  }
  if (probability > 0)
    for (double& v : p) v /= probability;
  return {probability, std::move(p)};
}

Evaluation evaluate(const StfModel& m, const Table& reference, const std::vector<double>& chi2_dof,
                    std::vector<double>* joint) {
  std::unique_ptr<DirectionGrid> grid = make_grid(reference.grid);
  const BinnedModel binned(m, reference, *grid);
  const QuadratureLevels levels(*grid);
  SmoothCellCache smooth(m, levels);
  Evaluation ev = evaluate_bins(reference, [&](int b) { return binned.bin(b, std::ref(smooth)); }, joint);
  if (chi2_dof.size() == ev.per_alpha.size()) {
    // Over the bins that have a value (fitted bins; borrowed and empty ones have -1).
    double sum = 0, weight = 0;
    for (std::size_t b = 0; b < chi2_dof.size(); ++b) {
      ev.per_alpha[b].chi2_dof = chi2_dof[b];
      if (chi2_dof[b] >= 0) sum += ev.per_alpha[b].weight * chi2_dof[b], weight += ev.per_alpha[b].weight;
    }
    ev.chi2_dof = weight > 0 ? sum / weight : -1;
  }
  ev.model_bytes = m.packed_bytes();
  ev.table_bytes = std::int64_t(reference.alpha_bins) * reference.cells * 4;
  return ev;
}

Evaluation evaluate(const Table& candidate, const Table& reference, std::vector<double>* joint) {
  if (alpha_group_size(candidate.alpha_edges, reference) != 1)
    throw std::invalid_argument("alpha bins differ from the reference's (" + std::to_string(candidate.alpha_bins) +
                                " vs " + std::to_string(reference.alpha_bins) + ")");
  if (candidate.grid != reference.grid)
    throw std::invalid_argument("grid " + candidate.grid + " differs from the reference's " + reference.grid);
  double escaped = 0;
  for (double w : candidate.weight()) escaped += w;
  Evaluation ev = evaluate_bins(reference, [&](int b) {
    double n;
    std::vector<double> p = bin_distribution(candidate, b, n);
    return std::pair(escaped > 0 ? n / escaped : 0.0, p);
  }, joint);
  ev.table_bytes = std::int64_t(candidate.alpha_bins) * candidate.cells * 4;
  return ev;
}

std::vector<double> expected_weights(const StfModel& model, const Table& table) {
  std::vector<double> joint;
  evaluate(model, table, {}, &joint);
  for (double& w : joint) w *= table.escaped_weight;
  return joint;
}

// JSON has no infinity: an infinite KL (the candidate misses cells the reference has) is written
// as null, as nlohmann-json writes every non-finite number.
std::string to_json(const Evaluation& e) {
  using nlohmann::ordered_json;
  auto known = [](double v, bool is) { return is ? ordered_json(v) : ordered_json(nullptr); };  // NaN: null
  ordered_json j = {{"tv_distance", e.tv},
                    {"joint_tv_distance", e.joint_tv},
                    {"kl_divergence", e.kl},
                    {"chi2_dof", known(e.chi2_dof, e.chi2_dof >= 0)},
                    {"model_bytes", e.model_bytes >= 0 ? ordered_json(e.model_bytes) : ordered_json(nullptr)},
                    {"table_bytes", e.table_bytes},
                    {"per_alpha", ordered_json::array()}};
  for (std::size_t b = 0; b < e.per_alpha.size(); ++b) {
    const BinError& x = e.per_alpha[b];
    j["per_alpha"].push_back({{"bin", b}, {"weight", x.weight}, {"tv_distance", x.tv}, {"kl_divergence", x.kl},
                              {"chi2_dof", known(x.chi2_dof, x.chi2_dof >= 0)}});
  }
  return j.dump(2) + "\n";
}

}  // namespace stf::measure
