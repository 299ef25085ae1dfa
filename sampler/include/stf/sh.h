// Real, orthonormal spherical harmonics up to band limit L: index l^2 + l + m, m in -l..l,
//   Y_l0 = N_l0 P_l(cos theta),  Y_lm = sqrt(2) N_lm P_l^m cos(m phi),
//   Y_l,-m = sqrt(2) N_lm P_l^m sin(m phi)   (m > 0, no Condon-Shortley phase),
// with N_lm = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!).
#pragma once

#include <vector>

#include "stf/vec3.h"

namespace stf {

inline int sh_count(int band_limit) { return (band_limit + 1) * (band_limit + 1); }

// Writes the sh_count(L) basis values at unit direction d to out.
void sh_basis(int band_limit, const Vec3& d, double* out);

// sum_i coefficients[i] * Y_i(d).
double sh_eval(int band_limit, const double* coefficients, const Vec3& d);

}  // namespace stf
