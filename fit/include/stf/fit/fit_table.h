// Fits a whole raw table: every alpha bin's direction histogram, the alpha marginal and the
// escape fractions, with model size chosen on the held-out half-table when asked.
#pragma once

#include "stf/fit/fit_settings.h"
#include "stf/core/table.h"

namespace stf::fit {

StfModel fit_table(const Table& table, const FitSettings& settings, FitReport* report = nullptr);

}  // namespace stf::fit
