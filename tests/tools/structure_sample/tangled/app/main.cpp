#include "inner.h"
#include "low.h"
#include "own.h"
#include "stf/lib/pub.h"
int main() { return pub() + inner() + own(); }
