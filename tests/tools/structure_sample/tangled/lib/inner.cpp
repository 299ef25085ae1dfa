#include "inner.h"
#include "stf/lib/pub.h"  // back up: inner is below pub
int inner() { return 1; }
