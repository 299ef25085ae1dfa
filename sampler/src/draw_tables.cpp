#include "stf/draw_tables.h"

namespace stf {

DrawTables::DrawTables(const StfModel& m) : lobes(m.lobes) {
  const int bins = m.bins();
  for (int b = 0; b < bins && m.kind == ModelKind::kVmf; ++b) {
    double sum = 0;
    for (const VmfLobe& l : m.lobes_of(b)) lobe_cdf.push_back(sum += l.weight);
  }
  // Cells have equal areas, so their masses are the table values.
  const std::size_t per_bin = std::size_t(2) * m.sh_nz * m.sh_nz;
  for (int b = 0; b < bins && m.kind == ModelKind::kSh; ++b)
    cells.emplace_back(std::vector<double>(m.sh_table.begin() + std::ptrdiff_t(b * per_bin),
                                           m.sh_table.begin() + std::ptrdiff_t((b + 1) * per_bin)));
  for (int b = 0; b < bins && m.hemispherical; ++b)
    outward.emplace_back(m.alpha_edges[std::size_t(b)], m.alpha_edges[std::size_t(b) + 1]);
  if (m.once_fraction > 0) once = OnceScattered(m.tau, m.g);
}

}  // namespace stf
