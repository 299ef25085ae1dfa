#include "stf/lib/pub.h"
#include "inner.h"
int pub() { return inner() + low(); }
