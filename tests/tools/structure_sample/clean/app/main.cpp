#include "stf/lib/pub.h"
int main() { return pub(); }
