#include "stf/lib/low.h"
int low() { return 2; }
