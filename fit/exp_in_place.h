#pragma once

namespace stf::fit {

// x[i] = e^x[i] for i < n, several at a time: the lobe integrals of a vMF fit spend a third of
// their time in exp, one call per quadrature point. Within a few units in the last place of
// std::exp (glibc's vector exp, libmvec); exponents here lie in [-60, 0].
void exp_in_place(double* x, int n);

}  // namespace stf::fit
