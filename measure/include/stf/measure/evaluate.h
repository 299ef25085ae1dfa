// Error of a model or a raw table against a reference table (docs/design.md, "Fitting and error").
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "stf/model.h"
#include "stf/core/grid.h"
#include "stf/fit/once_scattered_cells.h"
#include "stf/fit/vmf_fit.h"
#include "stf/core/table.h"

namespace stf::measure {

struct BinError {
  double tv = 0;          // 0.5 sum |p - q| over the reference's cells
  double kl = 0;          // sum q log(q / p) over cells with reference mass; inf if p = 0 there
  double chi2_dof = -1;   // against the fitting table (models only; -1 when not known)
  double weight = 0;      // the reference's alpha marginal in this bin
};

struct Evaluation {
  std::vector<BinError> per_alpha;
  double tv = 0, kl = 0;  // weighted by the reference's alpha marginal
  // TV of the joint (alpha bin, cell) exit distributions: also counts the alpha marginal's
  // error; what a tolerance (stf/measure/tolerance.h) bounds.
  double joint_tv = 0;
  double chi2_dof = -1;   // weighted likewise (models only)
  std::int64_t model_bytes = -1;  // models: packed size
  std::int64_t table_bytes = 0;   // the thesis's raw layout of the evaluated grid: bins * cells * 4
};

// Alpha bins given by `edges` must be the reference's or groups of f consecutive ones;
// returns f. Throws std::invalid_argument otherwise.
int alpha_group_size(const std::vector<double>& edges, const Table& reference);

// Per-cell probabilities of the fitted density of alpha bin b, integrated over the cells of the
// grid whose quadratures `levels` holds (build them once for all bins); they sum to 1.
// With `turn`, of the bin's density turned by that angle about y (StfModel::alpha_turn).
// Lifted lobes are mapped about the normals of the exit points with alpha in [exit_a0, exit_a1]
// (both 0: the bin's own).
std::vector<double> smooth_cell_probabilities(const StfModel& model, int bin, const fit::QuadratureLevels& levels,
                                              double turn = 0, double exit_a0 = 0, double exit_a1 = 0);

// A model's exit distribution in a reference table's layout, bin by reference bin, every part in
// its exact cells: the smooth part (model bins spread over the reference bins they group by
// their tilted density in area, as a sampler spreads alpha, and blended with neighbours as the
// sampler blends them), the uncollided delta in reference bin 0's cell of +z and
// the once-scattered part binned exactly.
class BinnedModel {
 public:
  // Throws std::invalid_argument when the model's alpha bins are not the reference's or groups
  // of them.
  BinnedModel(const StfModel& model, const Table& reference, const DirectionGrid& grid);
  int group() const { return group_; }
  // Reference bin b: its probability and its distribution over cells, from the smooth part's
  // cell probabilities of model bins (`smooth_cells(j, turn, a0, a1)`: smooth_cell_probabilities
  // of model bin j turned by `turn` at the exit angles [a0, a1], asked for b / group() and, in
  // blended models, its neighbours; the turn is 0 unless the model turns, and then the reference
  // bin is cut into slices of exit angle, each with its own turns).
  using SmoothCells = std::function<const std::vector<double>&(int, double, double, double)>;
  std::pair<double, std::vector<double>> bin(int b, const SmoothCells& smooth_cells) const;

 private:
  const StfModel& model_;
  const Table& reference_;
  int group_ = 1;
  std::int64_t pole_cell_ = 0;
  fit::OnceScatteredCells once_;
};

// Smooth cell probabilities of model bins as BinnedModel::bin asks for them, in ascending order
// of the reference bins: each computed once, as many kept as one reference bin needs.
class SmoothCellCache {
 public:
  SmoothCellCache(const StfModel& model, const fit::QuadratureLevels& levels) : model_(model), levels_(levels) {}
  const std::vector<double>& operator()(int j, double turn = 0, double exit_a0 = 0, double exit_a1 = 0);

 private:
  struct Kept {
    int bin;
    double turn, exit_a0, exit_a1;  // the exit angles count for lifted lobes alone
    std::vector<double> cells;
  };
  const StfModel& model_;
  const fit::QuadratureLevels& levels_;
  std::vector<Kept> kept_;
};

// A model's alpha bins may be groups of the reference's (a tolerance fit's): each reference
// bin is then compared with the model bin holding it. Throws std::invalid_argument when the
// alpha bins do not match that way (or, for tables, differ, or the grids differ). `joint`, when
// given, receives the candidate's exit distribution in the reference's layout: the probability
// of each (alpha bin, cell) per escape, row-major [bins, cells], summing to 1 (`stf eval --cells`).
Evaluation evaluate(const StfModel& model, const Table& reference, const std::vector<double>& chi2_dof = {},
                    std::vector<double>* joint = nullptr);
Evaluation evaluate(const Table& candidate, const Table& reference, std::vector<double>* joint = nullptr);

// A model's expected weights in a table's layout [bins * cells]: the table's escaped weight
// times each (alpha bin, cell)'s probability under the model, every part binned as `evaluate`
// bins it (`stf smooth`).
std::vector<double> expected_weights(const StfModel& model, const Table& table);

std::string to_json(const Evaluation& e);

}  // namespace stf::measure
