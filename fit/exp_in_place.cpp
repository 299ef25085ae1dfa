#include "stf/fit/exp_in_place.h"

#include <cmath>

namespace stf::fit {

// This file alone is built with -ffast-math (fit/CMakeLists.txt): glibc declares its vector
// exp only then, and the loop below is all the file holds, so nothing else depends on it.
void exp_in_place(double* x, int n) {
  for (int i = 0; i < n; ++i) x[i] = std::exp(x[i]);
}

}  // namespace stf::fit
