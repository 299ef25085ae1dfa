// `stf import`: a histogram stf did not make into a table; `stf smooth`: a table into its fitted
// model's expected weights, in the table's own layout (docs/formats.md, "Tables stf did not make").
#include <CLI/CLI.hpp>

#include <cstdio>
#include <memory>

#include "cli.h"
#include "stf/measure/evaluate.h"
#include "stf/fit/expected_singular.h"
#include "stf/fit/fit_table.h"
#include "stf/core/h5io.h"
#include "stf/core/import.h"
#include "stf/core/minimal_table.h"
#include "stf/precompute/precompute.h"

namespace stf::cli {

namespace {

struct ImportOptions {
  std::string histogram, grid, alpha_bins, paths, output;
  Medium medium;
  bool quiet = false;
};

// The medium when --sigma-s, --sigma-a and --g are all given, and none when none is.
bool medium_given(const CLI::App& cmd) {
  const int given = int(cmd.count("--sigma-s") > 0) + int(cmd.count("--sigma-a") > 0) + int(cmd.count("--g") > 0);
  if (given % 3 != 0 || (given == 0 && cmd.count("--radius")))
    fail("--sigma-s, --sigma-a and --g name the medium together (--radius with them, optional)");
  return given == 3;
}

std::vector<double> read_histogram(const std::string& path, const Table& layout, const DirectionGrid& grid) {
  const std::size_t dot = path.find_last_of('.');
  const std::string ext = dot == std::string::npos ? "" : path.substr(dot);
  try {
    if (ext == ".npy") return read_npy_counts(path, layout.alpha_bins, layout.cells);
    if (ext == ".csv" || ext == ".txt") return read_text_counts(path, layout, grid);
  } catch (const std::runtime_error& e) {
    fail(e.what());
  }
  fail("HIST must be a .npy, .csv or .txt file, got '" + path + "'");
}

void run_import(const ImportOptions& o, const CLI::App& cmd) {
  const bool medium = medium_given(cmd);
  PrecomputeSettings s;
  s.alpha_bins = int(parse_count(o.alpha_bins, "--alpha-bins", 1, kMaxAlphaBins));
  s.grid = o.grid;
  // validate() checks the grid and the table's size as precompute would; any medium serves.
  if (auto error = validate(medium ? o.medium : Medium{1, 0, 0, 1}, s)) fail(*error);
  const std::int64_t paths = o.paths.empty() ? -1 : parse_count(o.paths, "--paths", 1, std::int64_t(1) << 62);
  AtomicOutput out(o.output, "-o", {{o.histogram, "HIST"}});
  const std::unique_ptr<DirectionGrid> grid = make_grid(o.grid);
  Table layout;
  lay_out(layout, *grid, s.alpha_bins);
  const std::vector<double> counts = read_histogram(o.histogram, layout, *grid);
  double total = 0;
  for (double c : counts) total += c;
  if (paths >= 0 && double(paths) < total * (1 - 1e-12))
    fail("--paths (" + std::to_string(paths) + ") is fewer than the histogram's total count (" + std::to_string(total) + ")");
  stop_if_interrupted();
  out.write(minimal_table_file(layout, counts, [&](H5::H5File& f) {
    h5::put_attr(f, "format", std::string(kTableFormat));
    h5::put_attr(f, "format_version", kTableFormatVersion);
    h5::put_attr(f, "grid", layout.grid);
    h5::put_attr(f, "generator", std::string("stf " STF_VERSION " import"));
    h5::put_attr(f, "imported_from", o.histogram);
    if (paths >= 0) h5::put_attr(f, "paths", paths);
    if (medium) put_medium(f, o.medium);
  }));
  if (!o.quiet)
    std::fprintf(stderr, "stf import: %d alpha bins x %lld cells, total count %.17g -> %s\n", layout.alpha_bins,
                 (long long)layout.cells, total, o.output.c_str());
}

struct SmoothOptions {
  std::string table, output, model = "auto", threads = "0";
  bool quiet = false;
};

std::string chosen_spec(const StfModel& m, const fit::FitReport& r) {
  return std::string(m.family()) + ":" + std::to_string(r.chosen_size);
}

void run_smooth(const SmoothOptions& o) {
  fit::FitSettings settings = fit_settings(o.model, o.threads);
  AtomicOutput out(o.output, "-o", {{o.table, "the table"}});
  const Table table = read_table(o.table);
  if (std::string why = fit::settings_error(table, settings); !why.empty()) fail(o.table + ": " + why);
  // The output copies the input's attributes: taken now, so that one which cannot be copied fails
  // before the fit, and the input is not read a third time.
  h5::MemoryFile attributes;
  h5::read_file(o.table, [&](H5::H5File& f) { h5::copy_attributes(f, attributes.file()); });
  settings.run.cancel = &interrupted;
  StepStatus status("stf smooth", o.quiet);
  settings.run.progress = status.progress();
  fit::FitReport report;
  const StfModel model = fit::fit_table(table, settings, &report);
  status.finish();
  stop_if_interrupted();
  const std::vector<double> weights = measure::expected_weights(model, table);
  const std::string spec = chosen_spec(model, report);
  out.write(minimal_table_file(table, weights, [&](H5::H5File& f) {
    h5::copy_attributes(attributes.file(), f);
    for (const char* name : {"smoothed_by", "smoothed_from"})
      if (f.attrExists(name)) f.removeAttr(name);
    h5::put_attr(f, "smoothed_by", spec);
    h5::put_attr(f, "smoothed_from", o.table);
  }));
  if (!o.quiet)
    std::fprintf(stderr, "stf smooth: %s in %.3g s (singular parts: %s) -> %s\n", spec.c_str(), report.fit_time_s,
                 report.singular_parts.c_str(), o.output.c_str());
}

}  // namespace

void add_import_command(CLI::App& app) {
  auto o = std::make_shared<ImportOptions>();
  CLI::App* cmd = app.add_subcommand("import", "A histogram stf did not make (.npy, .csv, .txt) into a table");
  cmd->add_option("histogram", o->histogram, "HIST: .npy [alpha_bins, cells], or text rows 'alpha_bin cell count' or 'alpha theta phi count'")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--grid", o->grid, "Direction cells: csc:N or healpix:NSIDE (RING order)")->required();
  cmd->add_option("--alpha-bins", o->alpha_bins, "Equal bins of the exit-point angle alpha on [0, pi]")->required();
  cmd->add_option("-o,--output", o->output, "Output table (HDF5)")->required();
  cmd->add_option("--paths", o->paths, "Paths launched (default: the counts' total, as if every path escaped)");
  add_medium_options(*cmd, o->medium, false);  // all three or none (run_import)
  cmd->add_flag("--quiet", o->quiet, "No summary line");
  cmd->callback([o, cmd] { run_import(*o, *cmd); });
}

void add_smooth_command(CLI::App& app) {
  auto o = std::make_shared<SmoothOptions>();
  CLI::App* cmd = app.add_subcommand("smooth", "A table into its fitted model's expected weights, in the table's layout");
  cmd->add_option("table", o->table, "Table (HDF5): stf's, or any file with the four datasets")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", o->output, "Smoothed table (HDF5)")->required();
  add_fit_options(*cmd, o->model, o->threads);
  cmd->add_flag("--quiet", o->quiet, "No status line and no summary line");
  cmd->callback([o] { run_smooth(*o); });
}

}  // namespace stf::cli
