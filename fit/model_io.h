// The fitted model's HDF5 form (CONTRACT.md "Fitted model"; layout in README.md).
#pragma once

#include <string>

#include "fit_table.h"
#include "stf/model.h"
#include "table.h"

namespace stf::fit {

// Where a model came from, stored beside it.
struct Provenance {
  std::string model_spec;  // as given to --model
  std::string source_table;
  const Table* table = nullptr;  // its attributes are copied (paths, seed, grid, generator)
};

void write_model(const StfModel& model, const FitReport& report, const Provenance& provenance,
                 const std::string& path);
// Reads a model written by write_model (format_version 1); the SH tables are rebuilt.
StfModel read_model(const std::string& path);
// The per-bin chi^2 / dof of a model against the table it was fitted to.
std::vector<double> read_chi2_dof(const std::string& path);
// The "format" attribute of an stf HDF5 file ("stf-table", "stf-model"), or "" if none.
std::string file_format(const std::string& path);

}  // namespace stf::fit
