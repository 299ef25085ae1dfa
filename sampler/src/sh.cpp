#include "stf/sh.h"

#include <algorithm>
#include <cmath>

namespace stf {

// Normalised associated Legendre functions by the standard stable recurrences in m then l,
// carrying N_lm P_l^m directly so nothing overflows at high l.
void sh_basis(int L, const Vec3& d, double* out) {
  const double z = std::max(-1.0, std::min(1.0, d.z));
  const double rho = std::sqrt(std::max(0.0, 1 - z * z));
  const double phi = std::atan2(d.y, d.x);
  // pmm = N_mm P_m^m (without the sqrt(2) of m > 0).
  double pmm = std::sqrt(1 / (4 * kPi));
  for (int m = 0; m <= L; ++m) {
    if (m > 0) pmm *= std::sqrt((2.0 * m + 1) / (2.0 * m)) * rho;  // no Condon-Shortley phase
    double cm = m == 0 ? 1 : std::sqrt(2.0) * std::cos(m * phi);
    double sm = m == 0 ? 0 : std::sqrt(2.0) * std::sin(m * phi);
    double p_prev = 0, p = pmm;  // N_{l-1,m} P, N_{l,m} P at l = m
    for (int l = m; l <= L; ++l) {
      if (l > m) {
        double a = std::sqrt((4.0 * l * l - 1) / (double(l * l - m * m)));
        double b = std::sqrt(((l - 1.0) * (l - 1) - m * m) / (4.0 * (l - 1) * (l - 1) - 1));
        double next = a * (z * p - b * p_prev);
        p_prev = p;
        p = next;
      }
      out[l * l + l + m] = p * cm;
      if (m > 0) out[l * l + l - m] = p * sm;
    }
  }
}

double sh_eval(int L, const double* c, const Vec3& d) {
  std::vector<double> basis(sh_count(L));
  sh_basis(L, d, basis.data());
  double sum = 0;
  for (int i = 0; i < sh_count(L); ++i) sum += c[i] * basis[i];
  return sum;
}

}  // namespace stf
