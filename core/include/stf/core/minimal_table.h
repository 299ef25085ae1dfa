// Tables stf did not make (docs/formats.md, "Tables stf did not make"): a file that holds only
// the four datasets of a table. What the walk would have tallied besides them is made up here
// as the fit needs it: the grid recognised from its cells, and two half-tables for held-out
// scores drawn from the counts.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "stf/core/table.h"

namespace H5 {
class H5File;
}

namespace stf {

class DirectionGrid;

// Sets the table's grid, cells and alpha bins: `alpha_bins` equal bins of alpha on [0, pi], the
// grid's cell centres and solid angles.
void lay_out(Table& t, const DirectionGrid& grid, int alpha_bins);

// The two half-tables of a table whose file holds none: whole-number counts split by Poisson
// thinning, each count n as Binomial(n, 1/2) from a stream seeded by `seed` and the alpha bin
// (for Poisson counts the halves are independent Poisson counts of half the mean, exactly as
// the walk's even and odd paths); weighted counts split evenly (Halves::kEven). Sets
// t.weight_half and t.halves.
void split_halves(const std::vector<double>& weight, std::uint64_t seed, Table& t);

// Binomial(n, 1/2): the number of ones among n random bits of `state`'s splitmix64 stream.
std::uint64_t binomial_half(std::uint64_t n, std::uint64_t& state);

// The grid spec ("healpix:NSIDE" or "csc:N") whose cell count is `cells`, or "" when none has.
std::string grid_of_cells(std::int64_t cells);

// Why `direction` is not the cell centres of the grid `spec` in its own numbering (HEALPix RING,
// the cube as stf numbers it), or "" when it is.
std::string grid_mismatch(const std::string& spec, const std::vector<std::array<double, 3>>& direction);

// The bytes of an HDF5 table holding the four datasets of `layout` (its alpha edges, cell
// centres and solid angles) with `weight` [alpha_bins * cells] as /escape/weight (or /escape/
// `name`), and the root attributes `attributes` writes.
std::string minimal_table_file(const Table& layout, const std::vector<double>& weight,
                               const std::function<void(H5::H5File&)>& attributes, const char* name = "weight");


}  // namespace stf
