// The fitted model's HDF5 form (docs/formats.md, "Fitted model").
#pragma once

#include <string>

#include "stf/fit/fit_table.h"
#include "stf/model.h"
#include "stf/core/table.h"

namespace stf::fit {

// Where a model came from, stored beside it.
struct Provenance {
  std::string model_spec;  // as given to --model
  std::string source_table;
  const Table* table = nullptr;  // its attributes are copied (paths, seed, grid, generator)
  // Fits to a tolerance (stf/measure/tolerance.h): the target, the certified bound and the table
  // that certified it; tolerance <= 0 when the fit had none.
  double tolerance = 0, tv_bound = 0;
  bool tolerance_met = false;
  std::string fit_grid;  // the coarsened grid the model was fitted on
  std::string heldout_table;
  std::int64_t heldout_paths = 0;
};

// What a model file says about its resolution, for plans and reports.
struct ModelSummary {
  std::string kind;       // the family: "vmf", "hvmf" or "sh"
  int size = 0;           // lobes or band limit
  int alpha_bins = 0;
  std::string grid;       // it was fitted on
  std::int64_t paths = 0; // of that table
  std::int64_t bytes = 0; // packed
  double tolerance = 0, tv_bound = 0;  // tolerance <= 0: none
  bool tolerance_met = false;
};

// The model as the bytes of its HDF5 file.
std::string model_file(const StfModel& model, const FitReport& report, const Provenance& provenance);
// Replaces `path` by the model's file (replace_file: an old file survives any failure).
void write_model(const StfModel& model, const FitReport& report, const Provenance& provenance,
                 const std::string& path);
// Reads a model written by write_model (format_version 2, or 1: no uncollided fraction); the
// SH tables are rebuilt. Values are checked (model_error).
StfModel read_model(const std::string& path);
ModelSummary read_model_summary(const std::string& path);
// A model from an stf-model file, or the first entry of a pack (what `stf sample` and Python's
// stf.Model read). Throws std::runtime_error with one line naming the file.
StfModel read_model_or_pack(const std::string& path);
// The per-bin chi^2 / dof of a model against the table it was fitted to.
std::vector<double> read_chi2_dof(const std::string& path);
// The "format" attribute of an stf HDF5 file ("stf-table", "stf-model"), or "" if none.
std::string file_format(const std::string& path);

}  // namespace stf::fit
