// The singular parts of a table stf did not make: its counts hold the uncollided and the
// once-scattered escapes mixed with the rest, and no tally says which are which. Where the medium
// is known both parts' probabilities and cells are exact (e^{-tau} in bin 0's cell of +z; the
// one-collision quadrature, bin_once_scattered), so their expected counts stand in for the
// tallies, and the fit takes them out as it takes out the walk's.
#pragma once

#include <string>

#include "fit_table.h"
#include "table.h"

namespace stf::fit {

// True for a table whose file held no halves but names its medium.
bool wants_expected_singular_parts(const Table& t);

// The table with each half's singular tallies set to the part's expected count in every cell,
// paths times its probability (half each), but never more than the cell holds: a cell's count
// less its singular parts cannot fall below zero.
Table with_expected_singular_parts(const Table& t);

// How the fit of `t` took the singular parts out: "tallied", "expected from the medium" or
// "none" (nothing to take them out with: the table names no medium).
std::string singular_parts_source(const Table& t);

// Why `s` cannot be fitted to `t`, or "": the automatic choices need held-out halves, which
// weighted counts without /escape/weight_half do not have.
std::string settings_error(const Table& t, const FitSettings& s);

}  // namespace stf::fit
