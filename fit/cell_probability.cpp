#include "cell_probability.h"

#include <algorithm>
#include <cmath>

namespace stf::fit {

std::vector<double> vmf_cell_probabilities(const std::vector<VmfLobe>& lobes, const CellQuadrature& q,
                                           const std::vector<double>* factor) {
  const std::size_t cells = q.point.size() / q.per_cell;
  std::vector<double> p(cells, 0.0), mass(cells);
  for (const VmfLobe& lobe : lobes) {
    if (lobe.weight <= 0) continue;
    double total = 0;
    // The widened lobe and its normalisation depend on the sub-cell's solid angle alone: on an
    // equal-area grid (HEALPix) they are computed once per lobe. The density is vmf_pdf's, to
    // the bit: its normalisation over 2 pi, times the exponential.
    double widened_for = -1, kappa = 0, norm = 0;
    for (std::size_t c = 0; c < cells; ++c) {
      double m = 0;
      for (int j = 0; j < q.per_cell; ++j) {
        std::size_t k = c * q.per_cell + j;
        if (q.weight[k] != widened_for) {
          widened_for = q.weight[k], kappa = widened_kappa(lobe.kappa, q.weight[k]);
          norm = (kappa < 1e-12 ? 0.5 + 0.5 * kappa : kappa / -std::expm1(-2 * kappa)) / (2 * kPi);
        }
        m += q.weight[k] * (norm * std::exp(kappa * (dot(lobe.mean, q.point[k]) - 1))) * (factor ? (*factor)[k] : 1.0);
      }
      mass[c] = m;
      total += m;
    }
    if (!(total > 0)) continue;  // a hemispherical lobe wholly below the bin's tangent planes
    for (std::size_t c = 0; c < cells; ++c) p[c] += lobe.weight * mass[c] / total;
  }
  return p;
}

std::vector<double> density_cell_probabilities(const std::function<double(const Vec3&)>& density,
                                               const CellQuadrature& q) {
  const std::size_t cells = q.point.size() / q.per_cell;
  std::vector<double> p(cells, 0.0);
  double total = 0;
  for (std::size_t k = 0; k < q.point.size(); ++k) {
    double m = q.weight[k] * density(q.point[k]);
    p[k / q.per_cell] += m;
    total += m;
  }
  if (total > 0)
    for (double& v : p) v /= total;
  return p;
}

double poisson_deviance(const std::vector<double>& counts, const std::vector<double>& p) {
  double total = 0, d = 0;
  for (double n : counts) total += n;
  for (std::size_t c = 0; c < counts.size(); ++c) {
    double mu = total * p[c];
    if (counts[c] > 0) d += counts[c] * std::log(counts[c] / std::max(mu, 1e-300)) - counts[c];
    d += mu;
  }
  return 2 * d;
}

}  // namespace stf::fit
