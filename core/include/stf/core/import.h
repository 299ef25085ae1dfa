// Histograms stf did not make, read into a table's /escape/weight (docs/formats.md, "Import"):
// a .npy array [alpha_bins, cells], or text rows `alpha_bin cell count` or
// `alpha theta phi count`. Every failure is one line (std::runtime_error) naming the file and,
// for text, the line.
#pragma once

#include <string>
#include <vector>

#include "stf/core/grid.h"
#include "stf/core/table.h"

namespace stf {

// A .npy file (format 1.0 to 3.0) of shape [alpha_bins, cells] in C order, little-endian
// float64, float32, int64 or int32, as [alpha_bins * cells] counts (finite, >= 0).
std::vector<double> read_npy_counts(const std::string& path, int alpha_bins, std::int64_t cells);

// Text rows (comma or whitespace separated, `#` to the end of a line a comment), every row of
// the form of the first: `alpha_bin cell count` (0-based integers, the grid's own numbering) or
// `alpha theta phi count` (radians: the exit point's angle to the start direction; the exit
// direction's polar and azimuthal angles in the table's frame), binned into `layout`'s alpha
// bins and grid. Rows of one cell add up.
std::vector<double> read_text_counts(const std::string& path, const Table& layout, const DirectionGrid& grid);

}  // namespace stf
