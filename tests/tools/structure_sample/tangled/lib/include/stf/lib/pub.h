#pragma once
#include "stf/lib/low.h"
int pub();
