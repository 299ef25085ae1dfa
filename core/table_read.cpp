// Reading a table: stf's own, or any file with the four datasets (docs/formats.md, "Tables stf
// did not make"); what a file lacks is filled in, and the result is checked by table_error.
#include "stf/core/table.h"

#include <H5Cpp.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "stf/core/grid.h"
#include "stf/core/h5io.h"
#include "stf/core/minimal_table.h"

namespace stf {

using namespace h5;

namespace {

constexpr std::int64_t kMaxCount = h5::kMaxInt64;
constexpr double kMaxWeight = kMaxTotalWeight;

std::int64_t int64_or(const H5::H5File& file, const char* name, std::int64_t otherwise, std::int64_t lo) {
  return has_attr(file, name) ? get_int64(file, name, lo, kMaxCount) : otherwise;
}
double weight_or(const H5::H5File& file, const char* name, double otherwise) {
  return has_attr(file, name) ? get_double(file, name, 0, kMaxWeight) : otherwise;
}

// The medium as sigma_s, sigma_a, g (and radius, default 1), or as tau, albedo, g, each in its
// documented range; none at all leaves the table without one.
void read_medium(const H5::H5File& file, Table& t) {
  auto has = [&](const char* name) { return has_attr(file, name); };
  auto g = [&] { return get_double(file, "g", std::nextafter(-1.0, 0.0), std::nextafter(1.0, 0.0)); };
  if (has("sigma_s") && has("sigma_a") && has("g")) {
    t.medium = {get_double(file, "sigma_s", 0, kMaxWeight), get_double(file, "sigma_a", 0, kMaxWeight), g(),
                has("radius") ? get_double(file, "radius", 1e-300, kMaxWeight) : 1};
  } else if (has("tau") && has("albedo") && has("g")) {
    const double tau = get_double(file, "tau", 1e-300, kMaxWeight), albedo = get_double(file, "albedo", 0, 1);
    t.medium = {albedo * tau, (1 - albedo) * tau, g(), 1};
  } else if (has("sigma_s") || has("sigma_a") || has("g") || has("tau") || has("albedo") || has("radius")) {
    throw std::runtime_error("the medium is incomplete: give sigma_s, sigma_a and g (radius optional) or tau, albedo and g");
  } else {
    const double none = std::nan("");
    t.medium = {none, none, none, none};
  }
}

// Every attribute is optional (docs/formats.md, "Tables stf did not make"); totals a file lacks
// are -1 until settle_totals knows the escapes.
void read_header(const H5::H5File& file, Table& t) {
  if (has_attr(file, "format") && get_string(file, "format") != kTableFormat)
    throw std::runtime_error("not an stf table (format attribute is not 'stf-table')");
  if (has_attr(file, "format_version"))
    if (int v = get_int(file, "format_version"); v != kTableFormatVersion)
      throw std::runtime_error("unsupported table format_version " + std::to_string(v));
  read_medium(file, t);
  t.paths = int64_or(file, "paths", -1, 1);
  t.seed = int64_or(file, "seed", 0, h5::kMinInt64);
  t.max_scatter = int64_or(file, "max_scatter", -1, -1);
  t.safety_cap = int64_or(file, "safety_cap", 0, 0);
  t.grid = has_attr(file, "grid") ? get_string(file, "grid") : "";
  t.escaped_weight = weight_or(file, "escaped_weight", -1);
  t.absorbed_weight = weight_or(file, "absorbed_weight", -1);
  t.truncated_weight = weight_or(file, "truncated_weight", 0);
  t.collisions = int64_or(file, "collisions", 0, 0);
  t.absorbed_collisions = int64_or(file, "absorbed_collisions", -1, 0);
  t.runtime_s = has_attr(file, "runtime_s") ? get_double(file, "runtime_s", 0) : 0;
  t.generator = has_attr(file, "generator") ? get_string(file, "generator") : "";
  if (has_attr(file, "chunk_count")) {
    t.chunk_first = get_int64(file, "chunk_first", 0);
    t.chunk_last = get_int64(file, "chunk_last", 0);
    t.chunk_count = get_int64(file, "chunk_count", 0);
    t.run_paths = get_int64(file, "run_paths", 0);
  }
}

// Without `paths` every path escaped (the weights' sum, rounded up to a whole number); without
// the escaped and absorbed weights, they follow from the escapes and the paths.
void settle_totals(Table& t) {
  if (t.escaped_weight < 0) {
    t.escaped_weight = 0;
    for (const auto& half : t.weight_half)
      for (double w : half) t.escaped_weight += w;
    if (!(t.escaped_weight <= kMaxTotalWeight))
      throw std::runtime_error("/escape/weight sums to " + std::to_string(t.escaped_weight) + ", more than a table holds (2^62)");
  }
  if (t.paths < 0)
    t.paths = std::max<std::int64_t>(1, std::int64_t(std::ceil((t.escaped_weight + std::max(0.0, t.absorbed_weight) +
                                                                t.truncated_weight) * (1 - 1e-15))));
  if (t.absorbed_weight < 0) {
    t.absorbed_weight = double(t.paths) - t.escaped_weight - t.truncated_weight;
    if (t.absorbed_weight < -1e-9 * double(t.paths))
      throw std::runtime_error("paths (" + std::to_string(t.paths) + ") is fewer than the escaped weight (" +
                               std::to_string(t.escaped_weight) + ")");
    t.absorbed_weight = std::max(0.0, t.absorbed_weight);
  }
}

// /escape/weight is the table; its halves must add up to it (whole numbers: exactly, up to the
// rounding of weighted counts). Read row by row against the halves already read.
void check_weight_against_halves(const H5::H5File& file, const Table& t) {
  const hsize_t bins = hsize_t(t.alpha_bins), cells = hsize_t(t.cells);
  std::vector<double> row(cells);
  long current = -1;
  auto check = [&] {
    const std::size_t at = std::size_t(current) * cells;
    for (hsize_t c = 0; c < cells; ++c) {
      const double w = row[c], halves = t.weight_half[0][at + c] + t.weight_half[1][at + c];
      const std::string where = " (alpha bin " + std::to_string(current) + ", cell " + std::to_string(c) + ": ";
      if (!(std::isfinite(w) && w >= 0))
        throw std::runtime_error("/escape/weight holds a negative or non-finite weight" + where + std::to_string(w) + ")");
      if (std::abs(w - halves) > 1e-12 * (1 + w))
        throw std::runtime_error("/escape/weight and /escape/weight_half disagree" + where + std::to_string(w) +
                                 ", the halves sum to " + std::to_string(halves) + "); was the file changed?");
    }
  };
  // get_rows hands out one row at a time: check the previous row before the next is read.
  get_rows(file, "/escape/weight", {bins, cells}, [&](hsize_t b) {
    if (current >= 0) check();
    current = long(b);
    return row.data();
  });
  if (current >= 0) check();
}

// A table without halves: the tallies that belong to the halves cannot be read with it, and the
// halves are drawn from the weights (split_halves).
void read_weight_alone(const H5::H5File& file, Table& t) {
  for (const char* extra : {"/escape/uncollided_half", "/escape/once_half", "/escape/multiple_sub_half"})
    if (has_object(file, extra))
      throw std::runtime_error(std::string(extra) + " needs /escape/weight_half, which the file lacks");
  const std::vector<double> weight = get_dataset(file, "/escape/weight", {hsize_t(t.alpha_bins), hsize_t(t.cells)});
  for (std::size_t i = 0; i < weight.size(); ++i)
    if (!(std::isfinite(weight[i]) && weight[i] >= 0))
      throw std::runtime_error("/escape/weight holds a negative or non-finite weight (alpha bin " +
                               std::to_string(i / std::size_t(t.cells)) + ", cell " +
                               std::to_string(i % std::size_t(t.cells)) + ")");
  split_halves(weight, std::uint64_t(t.seed), t);
  t.uncollided_half = {-1, -1};
  t.once_tallied = false;
}

// The grid the table's cells make (or its grid attribute names, which must make as many), and
// room for the table, checked before anything is read.
void check_layout(const std::vector<hsize_t>& dims, Table& t) {
  if (dims.size() != 2) throw std::runtime_error("/escape/weight is not 2D");
  if (dims[0] < 1 || dims[0] > kMaxAlphaBins || dims[1] < 1)
    throw std::runtime_error("/escape/weight has " + std::to_string(dims[0]) + " alpha bins (1.." +
                             std::to_string(kMaxAlphaBins) + " allowed) and " + std::to_string(dims[1]) + " cells");
  t.alpha_bins = int(dims[0]);
  t.cells = std::int64_t(std::min<hsize_t>(dims[1], hsize_t(1) << 40));
  const std::string from_cells = grid_of_cells(t.cells);
  if (t.grid.empty() && from_cells.empty())
    throw std::runtime_error("no grid attribute, and " + std::to_string(t.cells) +
                             " cells are neither HEALPix (12 NSIDE^2, NSIDE a power of two) nor the cube (6 N^2)");
  if (!t.grid.empty()) {
    std::int64_t named = 0;
    try {
      named = grid_cell_count(t.grid);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(std::string("grid attribute: ") + e.what());
    }
    if (named != t.cells)
      throw std::runtime_error("the grid attribute names " + t.grid + " (" + std::to_string(named) +
                               " cells), /escape/weight has " + std::to_string(t.cells) + " cells");
  }
  // The weights, their two halves and a row's worth besides.
  require_memory(3.0 * 8 * double(dims[0]) * double(dims[1]), "the table of " + std::to_string(dims[0]) + " x " +
                                                                  std::to_string(dims[1]) + " weights");
}

void read_escapes(const H5::H5File& file, Table& t) {
  std::vector<hsize_t> dims = dataset_shape(file, "/escape/weight");
  check_layout(dims, t);
  t.alpha_edges = get_dataset(file, "/escape/alpha_edges", {dims[0] + 1});
  if (!has_object(file, "/escape/weight_half")) {
    read_weight_alone(file, t);
    return;
  }
  for (auto& half : t.weight_half) half.resize(dims[0] * dims[1]);
  get_rows(file, "/escape/weight_half", {2, dims[0], dims[1]},
           [&](hsize_t r) { return &t.weight_half[r / dims[0]][(r % dims[0]) * dims[1]]; });
  t.uncollided_half = {-1, -1};
  if (has_object(file, "/escape/uncollided_half")) {
    std::vector<double> u = get_dataset(file, "/escape/uncollided_half", {2});
    t.uncollided_half = {u[0], u[1]};
  }
  t.once_tallied = has_object(file, "/escape/once_half");
  if (t.once_tallied) t.once = get_sparse_halves(file, "/escape/once_half", t.alpha_bins, t.cells);
  if (has_object(file, "/escape/multiple_sub_half")) {
    std::vector<hsize_t> sub = dataset_shape(file, "/escape/multiple_sub_half");
    if (sub.size() != 3 || sub[0] != 2 || sub[1] != dims[0] || sub[2] < 1 || sub[2] > 1024)
      throw std::runtime_error("/escape/multiple_sub_half is not [2, alpha_bins, sub_bins]");
    t.sub_bins = int(sub[2]);
    for (auto& half : t.multiple_sub_half) half.resize(dims[0] * sub[2]);
    get_rows(file, "/escape/multiple_sub_half", {2, dims[0], sub[2]},
             [&](hsize_t r) { return &t.multiple_sub_half[r / dims[0]][(r % dims[0]) * sub[2]]; });
  }
}

void forget_once_tally(Table& t) {
  t.once.clear();
  t.once_tallied = false;
  t.sub_bins = 0;
  for (auto& half : t.multiple_sub_half) half.clear();
}

void read_grid(const H5::H5File& file, Table& t) {
  const hsize_t cells = hsize_t(t.cells);
  t.solid_angle = get_dataset(file, "/grid/solid_angle", {cells});
  std::vector<double> dir = get_dataset(file, "/grid/direction", {cells, 3});
  t.direction.resize(cells);
  for (std::size_t i = 0; i < cells; ++i) t.direction[i] = {dir[3 * i], dir[3 * i + 1], dir[3 * i + 2]};
  // Every table is checked against the grid it names, or the one its cells make (check_layout):
  // a wrong numbering, a negated direction or a file edited after it was written.
  const bool named = !t.grid.empty();
  if (!named) t.grid = grid_of_cells(t.cells);
  if (std::string why = grid_mismatch(t.grid, t.direction); !why.empty())
    throw std::runtime_error(why + (named ? "" : " (grid recognised from the cell count)"));
}

}  // namespace

Table read_table(const std::string& path) {
  return read_file(path, [](H5::H5File& file) {
    Table t;
    read_header(file, t);
    read_escapes(file, t);
    read_grid(file, t);
    settle_totals(t);
    // Without a medium the once-scattered part has no exact form (no tau, no g): its escapes are
    // fitted with the rest, as in a table that never tallied them, and so are the sub-bins of the
    // escapes after two or more collisions, which are counted apart from them (docs/formats.md,
    // "Tables stf did not make").
    if (!t.has_medium()) forget_once_tally(t);
    if (std::string why = table_error(t); !why.empty()) throw std::runtime_error(why);
    if (t.halves == Halves::kTallied) check_weight_against_halves(file, t);
    return t;
  });
}

}  // namespace stf
