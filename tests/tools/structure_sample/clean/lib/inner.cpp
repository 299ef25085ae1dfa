#include "inner.h"
#include "stf/lib/low.h"
int inner() { return low(); }
