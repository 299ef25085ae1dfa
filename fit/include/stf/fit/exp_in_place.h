#pragma once

namespace stf::fit {

// x[i] = e^x[i] for i < n, several at a time: the lobe integrals of a vMF fit spend a third of
// their time in exp, one call per quadrature point. Within a few units in the last place of
// std::exp (glibc's vector exp, libmvec); exponents here are at most 0, and far below it the
// result falls to denormals and 0 as std::exp's does.
void exp_in_place(double* x, int n);

}  // namespace stf::fit
