// The raw shell transport table (docs/formats.md, "Raw table") and its HDF5 form.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace H5 {
class Group;
class H5File;
}  // namespace H5

namespace stf {

// A homogeneous medium in a sphere. Only tau, albedo and g shape the table.
struct Medium {
  double sigma_s = 0, sigma_a = 0, g = 0, radius = 1;
  double sigma_t() const { return sigma_s + sigma_a; }
  double tau() const { return sigma_t() * radius; }
  double albedo() const { return sigma_s / sigma_t(); }
};

// How a table's two half-tables came about: tallied by the walk (or given in the file), drawn
// by Poisson thinning of whole-number counts (each count n splits as Binomial(n, 1/2)), or, for
// weighted counts, split evenly: then they are no held-out data, and fits choose nothing on them.
enum class Halves { kTallied, kThinned, kEven };

struct Table {
  Medium medium;
  // False for a table that names no medium (a histogram stf did not make): the medium's values
  // are NaN, and its model carries none.
  bool has_medium() const { return !std::isnan(medium.sigma_s); }
  Halves halves = Halves::kTallied;
  // True when the singular parts (uncollided_half, once) hold their expected counts from the
  // medium rather than the walk's tallies (stf/fit/expected_singular.h).
  bool singular_expected = false;
  std::int64_t paths = 0;
  std::int64_t seed = 0;
  std::int64_t max_scatter = -1;  // -1: unlimited but for the safety cap
  std::int64_t safety_cap = 0;    // the collision cap applied when max_scatter is -1
  std::string grid;               // "csc:N" or "healpix:NSIDE"
  int alpha_bins = 0;
  std::int64_t cells = 0;
  std::vector<double> alpha_edges;              // [alpha_bins + 1]
  std::vector<std::array<double, 3>> direction;  // [cells] cell centres
  std::vector<double> solid_angle;               // [cells]
  // Escaped weight per (alpha bin, cell) from the even- and odd-numbered paths: two
  // independent half-tables, so a fit can be scored on data it never saw.
  std::array<std::vector<double>, 2> weight_half;  // each [alpha_bins * cells]
  double escaped_weight = 0, absorbed_weight = 0, truncated_weight = 0;
  // Escapes without any collision (exit point alpha = 0, direction +z), per half; they are in
  // weight_half too. Tables written before stf recorded it read as -1 (unknown).
  std::array<double, 2> uncollided_half{0, 0};
  // Escapes after exactly one collision, in weight_half too, keyed by 2 (bin cells + cell) +
  // half (sparse: their directions lie in the plane y' = 0). Stored as /escape/once_half;
  // tables written before stf tallied them have once_tallied false.
  std::map<std::uint64_t, double> once;
  bool once_tallied = true;
  double once_weight() const;
  // Escapes after two or more collisions per half, alpha bin and sub-bin, [alpha_bins *
  // sub_bins]: how their density varies inside each alpha bin (in weight_half too). Sub-bin k
  // of bin b covers the area fractions u in [sub_edges[b (sub_bins + 1) + k], .. + k + 1] of
  // the bin, from its lower alpha edge; empty sub_edges: sub_bins equal parts. Stored as
  // /escape/multiple_sub_half [2, alpha_bins, sub_bins]; sub_bins is 0 for tables written
  // before stf tallied them.
  int sub_bins = 0;
  std::array<std::vector<double>, 2> multiple_sub_half;
  std::vector<double> sub_edges;
  double sub_edge(int b, int k) const {
    return sub_edges.empty() ? double(k) / sub_bins : sub_edges[std::size_t(b) * std::size_t(sub_bins + 1) + std::size_t(k)];
  }
  std::int64_t collisions = 0;  // scattering and absorption events over all paths
  // The absorbed paths' collisions, summed; -1 for tables written before stf tallied it.
  std::int64_t absorbed_collisions = -1;
  // Which chunks of the run's deterministic chunk stream the table holds: [chunk_first,
  // chunk_last) of chunk_count, for a run of run_paths paths. A part (stf precompute --shard)
  // holds a sub-range; parts that cover the run sum to its table (stf merge).
  std::int64_t chunk_first = 0, chunk_last = 0, chunk_count = 0, run_paths = 0;
  bool is_part() const { return chunk_last - chunk_first != chunk_count; }
  double runtime_s = 0;
  std::string generator;

  // The full table: the sum of the two halves.
  std::vector<double> weight() const;
};

// A sparse [2, bins, cells] array (keys 2 (bin cells + cell) + half) as a dense dataset, row by
// row, and back: what the table and a checkpoint store the once-scattered escapes as.
void put_sparse_halves(H5::Group& group, const char* name, int bins, std::int64_t cells,
                       const std::map<std::uint64_t, double>& values);
std::map<std::uint64_t, double> get_sparse_halves(const H5::H5File& file, const char* path, int bins,
                                                  std::int64_t cells);

// The most alpha bins a table may have (precompute, import and every reader), and the largest
// weight or total it may hold (whole-number counts are exact in float64 to 2^53).
inline constexpr int kMaxAlphaBins = 100000;
inline constexpr double kMaxTotalWeight = 0x1p62;

// The layout stf writes: a raw table's `format` and `format_version`.
inline constexpr const char* kTableFormat = "stf-table";
inline constexpr int kTableFormatVersion = 1;

// The medium's root attributes as stf's tables carry them.
void put_medium(H5::H5File& file, const Medium& medium);

// The table as the bytes of its HDF5 file.
std::string table_file(const Table& table);
// Replaces `path` by the table's file (replace_file: an old file survives any failure).
// Throws std::runtime_error on failure.
void write_table(const Table& table, const std::string& path);
// Why `t` is not a consistent table (values, not just shapes: non-finite or negative weights,
// totals that do not add up, bad edges or cells), or empty when it is.
std::string table_error(const Table& t);
// Reads a table written by write_table (format_version 1), or any HDF5 file holding its four
// datasets (/escape/weight, /escape/alpha_edges, /grid/direction, /grid/solid_angle), and checks
// it with table_error. What such a file lacks is filled in as docs/formats.md ("Tables stf did
// not make") says: paths from the weights' sum, the grid from its cells, halves by thinning.
// Throws std::runtime_error.
Table read_table(const std::string& path);

}  // namespace stf
