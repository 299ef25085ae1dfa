// The singular parts of a table stf did not make: its counts hold the uncollided and the
// once-scattered escapes mixed with the rest, and no tally says which are which. Where the medium
// is known both parts' probabilities and cells are exact (e^{-tau} in bin 0's cell of +z; the
// one-collision quadrature, bin_once_scattered), so their expected counts stand in for the
// tallies, and the fit takes them out as it takes out the walk's.
#pragma once

#include <string>

#include "stf/fit/fit_settings.h"
#include "stf/core/table.h"

namespace stf::fit {

// True for a table whose file held no halves (and so no tallies of the singular parts).
bool wants_expected_singular_parts(const Table& t);

// The table with each half's singular tallies set to the part's expected count in every cell,
// paths times its probability (half each), but never more than the cell holds: a cell's count
// less its singular parts cannot fall below zero. Without a medium only the uncollided part is
// known, by where it lies: bin 0's cell of +z holds it, and whatever else that one cell holds
// leaves it at the same cell; kept as the delta it is, the fit neither smears it over the four
// HEALPix cells that meet at the pole nor folds it off the pole (mirror_cells).
Table with_expected_singular_parts(const Table& t);

// How the fit of `t` took the singular parts out: "tallied", "expected from the medium" or,
// without a medium, "none but bin 0's cell of +z as the uncollided part".
std::string singular_parts_source(const Table& t);

// Why `s` cannot be fitted to `t`, or "": the automatic choices need held-out halves, which
// weighted counts without /escape/weight_half do not have.
std::string settings_error(const Table& t, const FitSettings& s);

}  // namespace stf::fit
