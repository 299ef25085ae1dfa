#include "stf/fit/expected_singular.h"

#include <algorithm>
#include <cmath>

#include "fit_stages.h"
#include "stf/fit/once_scattered_cells.h"

namespace stf::fit {

bool wants_expected_singular_parts(const Table& t) {
  return t.halves != Halves::kTallied && !t.singular_expected && !stages::singular_parts_exact(t);
}

Table with_expected_singular_parts(const Table& t) {
  Table e = t;
  e.singular_expected = true;
  const std::unique_ptr<DirectionGrid> grid = make_grid(t.grid);
  const std::size_t pole = std::size_t(grid->cell({0, 0, 1}));
  if (!t.has_medium()) {
    for (int h = 0; h < 2; ++h) e.uncollided_half[h] = t.weight_half[h][pole];
    return e;
  }
  const stages::SingularParts p = stages::medium_singular_parts(t);
  const double paths = double(t.paths);
  for (int h = 0; h < 2; ++h) e.uncollided_half[h] = std::min(t.weight_half[h][pole], 0.5 * paths * p.uncollided);
  e.once.clear();
  if (p.once > 0) {
    const OnceScatteredCells once = bin_once_scattered(t.medium.tau(), t.medium.g, t.alpha_edges, *grid);
    for (std::size_t b = 0; b < once.cells.size(); ++b)
      for (const auto& [cell, share] : once.cells[b]) {
        const std::size_t i = b * std::size_t(t.cells) + std::size_t(cell);
        for (int h = 0; h < 2; ++h)
          if (const double count = std::min(t.weight_half[h][i], 0.5 * paths * p.once * share); count > 0)
            e.once[2 * std::uint64_t(i) + std::uint64_t(h)] = count;
      }
  }
  e.once_tallied = true;
  return e;
}

std::string singular_parts_source(const Table& t) {
  if (t.singular_expected) return t.has_medium() ? "expected from the medium" : "none but bin 0's cell of +z as the uncollided part";
  return stages::singular_parts_exact(t) ? "tallied" : "none";
}

std::string settings_error(const Table& t, const FitSettings& s) {
  // The model must fit the limits its readers hold it to (stf/model.h): checked before the fit,
  // not found after it.
  if (s.kind == ModelKind::kSh) {
    const std::vector<int> sizes = s.automatic ? auto_candidates(s.kind) : std::vector<int>{s.size};
    const int largest = *std::max_element(sizes.begin(), sizes.end());
    if (std::string why = model_size_error(true, t.alpha_bins, largest, sh_table_rows(largest), s.alpha_degree); !why.empty())
      return "an SH model of band limit " + std::to_string(largest) + " over " + std::to_string(t.alpha_bins) +
             " alpha bins is beyond what a model holds (" + why + "): use a smaller band limit or fewer alpha bins";
  }
  if (t.halves != Halves::kEven || !s.automatic) return "";
  return "the table's weights are not whole numbers and it has no /escape/weight_half: --model auto and the "
         "auto sizes choose on held-out halves, which such a table lacks; give a fixed size (vmf:K, hvmf:K or sh:L)";
}

}  // namespace stf::fit
