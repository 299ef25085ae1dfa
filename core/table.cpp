#include "stf/core/table.h"

#include <H5Cpp.h>

#include <cmath>
#include <stdexcept>

#include "stf/core/files.h"
#include "stf/core/h5io.h"
#include "stf/model.h"
#include "stf/vec3.h"

namespace stf {

std::vector<double> Table::weight() const {
  std::vector<double> sum(weight_half[0]);
  for (std::size_t i = 0; i < sum.size(); ++i) sum[i] += weight_half[1][i];
  return sum;
}

double Table::once_weight() const {
  double sum = 0;
  for (const auto& [key, count] : once) sum += count;
  return sum;
}

using namespace h5;

void put_sparse_halves(H5::Group& group, const char* name, int bins, std::int64_t cells,
                       const std::map<std::uint64_t, double>& values) {
  const hsize_t rows = 2 * hsize_t(bins), n = hsize_t(cells);
  // Row r = half * bins + bin; key / 2 = bin * cells + cell.
  std::vector<std::vector<std::pair<std::int64_t, double>>> by_row(rows);
  for (const auto& [key, v] : values) {
    const std::uint64_t i = key >> 1;
    by_row[(key & 1) * hsize_t(bins) + i / n].emplace_back(std::int64_t(i % n), v);
  }
  std::vector<double> row(n, 0.0);
  std::size_t last = 0;
  put_rows(group, name, {2, hsize_t(bins), n}, [&](hsize_t r) {
    for (const auto& [c, v] : by_row[last]) row[std::size_t(c)] = 0;
    for (const auto& [c, v] : by_row[r]) row[std::size_t(c)] = v;
    last = r;
    return row.data();
  });
}

std::map<std::uint64_t, double> get_sparse_halves(const H5::H5File& file, const char* path, int bins,
                                                  std::int64_t cells) {
  std::map<std::uint64_t, double> values;
  std::vector<double> row(static_cast<std::size_t>(cells));
  hsize_t current = 0;
  auto keep_row = [&] {
    const std::uint64_t half = current / hsize_t(bins), bin = current % hsize_t(bins);
    for (std::int64_t c = 0; c < cells; ++c)
      if (row[std::size_t(c)] != 0) values[2 * (bin * std::uint64_t(cells) + std::uint64_t(c)) + half] = row[std::size_t(c)];
  };
  // get_rows hands out one row at a time: keep the previous row's values before the next read.
  bool any = false;
  get_rows(file, path, {2, hsize_t(bins), hsize_t(cells)}, [&](hsize_t r) {
    if (any) keep_row();
    any = true;
    current = r;
    return row.data();
  });
  if (any) keep_row();
  return values;
}

void put_medium(H5::H5File& file, const Medium& m) {
  h5::put_attr(file, "sigma_s", m.sigma_s);
  h5::put_attr(file, "sigma_a", m.sigma_a);
  h5::put_attr(file, "g", m.g);
  h5::put_attr(file, "radius", m.radius);
  h5::put_attr(file, "tau", m.tau());
  h5::put_attr(file, "albedo", m.albedo());
}

std::string table_file(const Table& t) {
  try {
    H5::Exception::dontPrint();
    MemoryFile memory;
    H5::H5File& file = memory.file();
    put_attr(file, "format", std::string(kTableFormat));
    put_attr(file, "format_version", kTableFormatVersion);
    if (t.has_medium()) put_medium(file, t.medium);  // a table of no medium names none
    put_attr(file, "paths", t.paths);
    put_attr(file, "seed", t.seed);
    put_attr(file, "max_scatter", t.max_scatter);
    put_attr(file, "safety_cap", t.safety_cap);
    put_attr(file, "grid", t.grid);
    put_attr(file, "escaped_weight", t.escaped_weight);
    put_attr(file, "absorbed_weight", t.absorbed_weight);
    put_attr(file, "truncated_weight", t.truncated_weight);
    put_attr(file, "collisions", t.collisions);
    if (t.absorbed_collisions >= 0) put_attr(file, "absorbed_collisions", t.absorbed_collisions);
    put_attr(file, "runtime_s", t.runtime_s);
    put_attr(file, "generator", t.generator);
    put_attr(file, "chunk_first", t.chunk_first);
    put_attr(file, "chunk_last", t.chunk_last);
    put_attr(file, "chunk_count", t.chunk_count);
    put_attr(file, "run_paths", t.run_paths);

    const hsize_t bins = hsize_t(t.alpha_bins), cells = hsize_t(t.cells);
    H5::Group escape = file.createGroup("/escape");
    // Row by row: a fine grid's table is gigabytes, and whole-table copies would double that.
    std::vector<double> sum(cells);
    put_rows(escape, "weight", {bins, cells}, [&](hsize_t b) {
      for (hsize_t c = 0; c < cells; ++c) sum[c] = t.weight_half[0][b * cells + c] + t.weight_half[1][b * cells + c];
      return sum.data();
    });
    put_dataset(escape, "uncollided_half", {2}, t.uncollided_half.data());
    put_attr(file, "uncollided_weight", t.uncollided_half[0] + t.uncollided_half[1]);
    if (t.once_tallied) {
      put_sparse_halves(escape, "once_half", t.alpha_bins, t.cells, t.once);
      put_attr(file, "once_weight", t.once_weight());
    }
    if (t.sub_bins > 0) {
      if (!t.sub_edges.empty()) throw std::runtime_error("a coarsened table's sub-bins have no file form");
      put_rows(escape, "multiple_sub_half", {2, bins, hsize_t(t.sub_bins)},
               [&](hsize_t r) { return &t.multiple_sub_half[r / bins][(r % bins) * hsize_t(t.sub_bins)]; });
    }
    put_rows(escape, "weight_half", {2, bins, cells},
             [&](hsize_t r) { return &t.weight_half[r / bins][(r % bins) * cells]; });
    put_dataset(escape, "alpha_edges", {bins + 1}, t.alpha_edges.data());

    H5::Group grid = file.createGroup("/grid");
    put_dataset(grid, "direction", {cells, 3}, t.direction.front().data());
    put_dataset(grid, "solid_angle", {cells}, t.solid_angle.data());
    escape.close();
    grid.close();
    return memory.bytes();
  } catch (const H5::Exception& e) {
    throw std::runtime_error("cannot write a table: " + e.getDetailMsg());
  }
}

void write_table(const Table& t, const std::string& path) { replace_file(path, table_file(t)); }

namespace {

// The sub-bin tallies must add up, per half and alpha bin, to the bin's escapes less those
// after fewer than two collisions (all whole numbers).
std::string multiple_sub_error(const Table& t) {
  if (t.sub_bins == 0) return "";
  if (t.sub_bins < 1 || !t.once_tallied || t.uncollided_half[0] < 0)
    return "/escape/multiple_sub_half needs /escape/once_half and /escape/uncollided_half";
  const std::size_t cells = std::size_t(t.cells), subs = std::size_t(t.sub_bins);
  std::vector<double> fewer(2 * std::size_t(t.alpha_bins), 0.0);  // [half * bins + bin]
  for (const auto& [key, w] : t.once) fewer[(key & 1) * std::size_t(t.alpha_bins) + (key >> 1) / cells] += w;
  for (int h = 0; h < 2; ++h) {
    fewer[std::size_t(h) * std::size_t(t.alpha_bins)] += t.uncollided_half[std::size_t(h)];
    for (int b = 0; b < t.alpha_bins; ++b) {
      double escapes = 0, multiple = 0;
      for (std::size_t c = 0; c < cells; ++c) escapes += t.weight_half[std::size_t(h)][std::size_t(b) * cells + c];
      for (std::size_t k = 0; k < subs; ++k) {
        const double w = t.multiple_sub_half[std::size_t(h)][std::size_t(b) * subs + k];
        if (!(std::isfinite(w) && w >= 0)) return "/escape/multiple_sub_half holds a negative or non-finite weight";
        multiple += w;
      }
      if (std::abs(escapes - fewer[std::size_t(h) * std::size_t(t.alpha_bins) + std::size_t(b)] - multiple) > 1e-6 * (1 + escapes))
        return "/escape/multiple_sub_half of alpha bin " + std::to_string(b) +
               " does not sum to its escapes after two or more collisions";
    }
  }
  return "";
}

}  // namespace

std::string table_error(const Table& t) {
  const Medium& m = t.medium;
  if (t.has_medium() && !(std::isfinite(m.sigma_s) && std::isfinite(m.sigma_a) && m.sigma_s >= 0 && m.sigma_a >= 0 &&
                        m.sigma_t() > 0 && std::isfinite(m.radius) && m.radius > 0 && m.g > -1 && m.g < 1))
    return "medium attributes out of range (sigma_s, sigma_a >= 0 and not both 0, radius > 0, g in (-1, 1))";
  if (t.has_medium() && !(m.tau() <= kMaxModelTau))
    return "the medium's tau (" + std::to_string(m.tau()) + ") is above 1e7, the largest stf precomputes";
  if (t.paths < 1 || t.alpha_bins < 1 || t.cells < 1) return "paths, alpha bins and cells must be at least 1";
  if (t.chunk_count > 0 && !(0 <= t.chunk_first && t.chunk_first < t.chunk_last && t.chunk_last <= t.chunk_count &&
                             t.paths <= t.run_paths))
    return "chunk range out of order (chunk_first, chunk_last, chunk_count, run_paths)";
  auto count = [](double w) { return std::isfinite(w) && w >= 0; };
  if (!count(t.escaped_weight) || !count(t.absorbed_weight) || !count(t.truncated_weight))
    return "escaped, absorbed and truncated weights must be finite and >= 0";
  const double paths = double(t.paths);
  if (std::abs(t.escaped_weight + t.absorbed_weight + t.truncated_weight - paths) > 1e-9 * paths)
    return "escaped + absorbed + truncated weight is not the number of paths";
  if (t.absorbed_collisions >= 0 && !(t.absorbed_weight <= double(t.absorbed_collisions) && t.absorbed_collisions <= t.collisions))
    return "absorbed_collisions must lie between the absorbed paths and all collisions";
  double escaped = 0;
  for (const auto& half : t.weight_half)
    for (double w : half) {
      if (!count(w)) return "/escape/weight_half holds a negative or non-finite weight";
      escaped += w;
    }
  if (std::abs(escaped - t.escaped_weight) > 1e-9 * paths)
    return t.halves == Halves::kTallied ? "/escape/weight_half does not sum to escaped_weight"
                                        : "/escape/weight does not sum to escaped_weight";
  for (double u : t.uncollided_half)
    if (!(u == -1 || (u >= 0 && u <= t.escaped_weight))) return "/escape/uncollided_half out of range";
  for (const auto& [key, w] : t.once) {
    const std::uint64_t i = key >> 1;
    if (i >= std::uint64_t(t.alpha_bins) * std::uint64_t(t.cells) || !count(w) || w > t.weight_half[key & 1][i])
      return "/escape/once_half of alpha bin " + std::to_string(i / std::uint64_t(t.cells)) + ", cell " +
             std::to_string(i % std::uint64_t(t.cells)) + " is negative, not finite or above the cell's escaped weight";
  }
  if (std::string why = multiple_sub_error(t); !why.empty()) return why;
  const auto& e = t.alpha_edges;
  if (e.front() != 0 || std::abs(e.back() - kPi) > 1e-12) return "/escape/alpha_edges must run from 0 to pi";
  for (std::size_t b = 0; b + 1 < e.size(); ++b)
    if (!(e[b + 1] - e[b] >= kMinAlphaBinWidth))
      return "/escape/alpha_edges must increase by at least 1e-6 rad (bin " + std::to_string(b) + ")";
  double total = 0;
  for (std::int64_t c = 0; c < t.cells; ++c) {
    const auto& d = t.direction[c];
    if (!(t.solid_angle[c] > 0 && std::isfinite(t.solid_angle[c])))
      return "/grid/solid_angle of cell " + std::to_string(c) + " is not > 0 and finite";
    if (!(std::abs(d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - 1) < 1e-6))
      return "/grid/direction of cell " + std::to_string(c) + " is not a unit vector";
    total += t.solid_angle[c];
  }
  if (std::abs(total - 4 * kPi) > 1e-6 * 4 * kPi) return "/grid/solid_angle does not sum to 4 pi";
  return "";
}

}  // namespace stf
