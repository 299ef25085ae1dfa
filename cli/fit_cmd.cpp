// `stf fit`: a raw table to a compact model; `stf eval`: error against a reference table.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>

#include "cli.h"
#include "stf/measure/evaluate.h"
#include "stf/fit/expected_singular.h"
#include "stf/fit/fit_table.h"
#include "stf/core/h5io.h"
#include "stf/core/minimal_table.h"
#include "stf/fit/model_io.h"
#include "stf/pack.h"
#include "stf/measure/tolerance.h"

namespace stf::cli {

namespace {

struct FitOptions {
  std::string table, model = "auto", output, report, pack;
  std::string threads = "0";
  int alpha_degree = -1;
  std::string ablate;
  double tolerance = 0;
  std::string heldout;
  bool quiet = false;
};

using nlohmann::ordered_json;

// The held-out choices of the blend and the pools, where the fit made them.
void add_choices(ordered_json& j, const fit::FitReport& r, const StfModel& m) {
  if (!r.blend_heldout_nll.empty()) {
    j["alpha_blend"] = m.alpha_blend;
    j["blend_heldout_nll"] = r.blend_heldout_nll;
    j["blend_heldout_nll_error"] = r.blend_heldout_nll_error;
    j["blend_width"] = r.blend_width;
    j["blend_by_bin_gain"] = r.blend_by_bin_gain;
    j["blend_by_bin_error"] = r.blend_by_bin_error;
    if (!m.alpha_blend_width.empty()) j["alpha_blend_width"] = m.alpha_blend_width;
  }
  if (!r.pool_sizes.empty()) {
    j["neighbour_weight"] = r.neighbour_weight;
    ordered_json pools = {{"unpooled", r.pool_heldout_nll[0]}};
    for (std::size_t i = 0; i < r.pool_sizes.size(); ++i)
      pools["pooled " + std::to_string(r.pool_sizes[i])] = r.pool_heldout_nll[i + 1];
    j["pool_heldout_nll"] = pools;
  }
}

// The per-bin diagnostics.
ordered_json bins_json(const fit::FitReport& r, const StfModel& m) {
  ordered_json bins = ordered_json::array();
  for (std::size_t b = 0; b < r.bins.size(); ++b) {
    const fit::BinDiagnostics& d = r.bins[b];
    ordered_json bin = {{"bin", b}, {"status", int(m.status[b])}, {"escapes", d.escapes}, {"components", d.components},
                        {"deviance", d.deviance}, {"chi2_dof", d.chi2_dof}};
    if (!r.pools.empty()) bin["pool_width"] = r.pools[b].width, bin["pool_sloped"] = r.pools[b].sloped;
    bins.push_back(bin);
  }
  return bins;
}

std::string report_json(const fit::FitReport& r, const StfModel& m, const std::string& spec) {
  ordered_json j = {{"model", spec}, {"chosen_size", r.chosen_size}, {"smoothing", r.smoothing},
                    {"window", r.lanczos_window ? "lanczos" : "none"}, {"alpha_penalty", r.alpha_penalty},
                    {"singular_parts", r.singular_parts}, {"heldout_halves", r.heldout_halves}, {"family", m.family()}};
  add_choices(j, r, m);
  j["fit_time_s"] = r.fit_time_s;
  j["model_bytes"] = m.packed_bytes();
  j["escape_probability"] = m.escape_probability;
  j["candidates"] = ordered_json::array();
  for (std::size_t i = 0; i < r.candidates.size(); ++i)
    j["candidates"].push_back(
        {{"size", r.candidates[i]}, {"heldout_nll", r.heldout_nll[i]}, {"heldout_nll_error", r.heldout_nll_error[i]}});
  j["per_alpha"] = bins_json(r, m);
  return j.dump(2) + "\n";
}

// A table whose medium and tallies disagree (an edited file) can fit to no valid model.
void refuse_invalid(const StfModel& model, const std::string& table) {
  if (std::string why = model_error(model); !why.empty())
    fail(table + ": the model fitted to it is not valid (" + why + "): do its medium and its tallies belong together?");
}

// --tolerance: resolution and size chosen and certified on the --heldout table.
measure::ToleranceFit fit_to_tolerance(const FitOptions& o, const Table& table, const fit::FitSettings& settings,
                                   fit::Provenance& provenance, StepStatus& status) {
  if (o.heldout.empty()) fail("--tolerance needs --heldout: an independent table of the same medium (another --seed)");
  if (o.alpha_degree >= 0) fail("--alpha-degree and --tolerance cannot be combined");
  const double tolerance = o.tolerance;
  Table heldout = read_table(o.heldout);
  if (std::string why = measure::heldout_error(table, heldout); !why.empty()) fail("--heldout " + why);
  measure::ToleranceFit r = measure::fit_to_tolerance(table, heldout, tolerance, settings);
  status.finish();
  stop_if_interrupted();  // a cancelled search has no result to state
  provenance.tolerance = tolerance, provenance.tv_bound = r.certificate.tv_bound, provenance.tolerance_met = r.met;
  provenance.heldout_table = o.heldout, provenance.heldout_paths = heldout.paths;
  provenance.fit_grid = r.fitted.grid;
  if (!o.quiet) {
    std::string tried;
    for (auto [size, bound] : r.attempts) {
      char item[64];
      std::snprintf(item, sizeof item, " %d: %.3g", size, bound);
      tried += item;
    }
    std::fprintf(stderr, "stf fit: TV bound by size:%s\n", tried.c_str());
    std::fprintf(stderr, "stf fit: %d alpha bins, %s, size %d: TV <= %.3g (%s %.3g)\n", r.fitted.alpha_bins,
                 r.fitted.grid.c_str(), r.size, r.certificate.tv_bound, r.met ? "within" : "NOT within", tolerance);
    if (r.lifted_bound >= 0)
      std::fprintf(stderr, "stf fit: lifted lobes reached TV <= %.3g only: hemispherical lobes kept\n", r.lifted_bound);
  }
  return r;
}

void run_fit(const FitOptions& o, const CLI::App& cmd) {
  fit::FitSettings settings = fit_settings(o.model, o.threads);
  if (o.alpha_degree >= 0 && settings.kind != ModelKind::kSh) fail("--alpha-degree applies to sh models only");
  if (o.alpha_degree < -1 || o.alpha_degree > 64) fail("--alpha-degree must be in 0..64 (or -1: off)");
  if (cmd.count("--tolerance") && !(o.tolerance > 0 && o.tolerance < 1))
    fail("--tolerance must be a TV distance in (0, 1), got " + std::to_string(o.tolerance));
  if (!o.heldout.empty() && !cmd.count("--tolerance")) fail("--heldout applies only with --tolerance");
  settings.alpha_degree = o.alpha_degree;
  if (cmd.count("--ablate")) {
    try {
      fit::ablate(settings, o.ablate);
    } catch (const std::invalid_argument& e) {
      fail(e.what());
    }
  }

  // Every output is checked (and claimed) before any work.
  std::vector<NamedFile> files{{o.table, "the table"}, {o.heldout, "--heldout"}};
  AtomicOutput out(o.output, "-o", files);
  files.push_back(out.named());
  std::optional<AtomicOutput> report_out, pack_out;
  if (!o.report.empty()) files.push_back(report_out.emplace(o.report, "--report", files).named());
  if (!o.pack.empty()) pack_out.emplace(o.pack, "--pack", files);

  Table table = read_table(o.table);
  if (std::string why = fit::settings_error(table, settings); !why.empty()) fail(o.table + ": " + why);
  if (cmd.count("--tolerance") && table.halves == Halves::kEven)
    fail(o.table + ": --tolerance chooses on held-out halves, which a table of weights without /escape/weight_half lacks");
  if (pack_out && !table.has_medium())
    fail(o.table + " names no medium, and a pack needs one (tau, albedo, g): import the histogram with --sigma-s, --sigma-a and --g");
  settings.run.cancel = &interrupted;
  StepStatus status("stf fit", o.quiet);
  settings.run.progress = status.progress();
  fit::FitReport report;
  StfModel model;
  fit::Provenance provenance;
  provenance.model_spec = o.model, provenance.source_table = o.table, provenance.table = &table;
  std::optional<measure::ToleranceFit> tolerant;
  if (!cmd.count("--tolerance")) {
    model = fit::fit_table(table, settings, &report);
  } else {
    tolerant = fit_to_tolerance(o, table, settings, provenance, status);
    model = tolerant->model, report = tolerant->report;
  }
  status.finish();
  stop_if_interrupted();
  refuse_invalid(model, o.table);
  // All staged first: a full disk leaves every old output as it was.
  out.stage(fit::model_file(model, report, provenance));
  if (report_out) report_out->stage(report_json(report, model, o.model));
  if (pack_out) {
    if (std::string why = pack_entry_error({"", model}); !why.empty()) fail("--pack: the model cannot go into a pack: " + why);
    pack_out->stage(bytes_of(write_pack({PackEntry{"", model}})));
  }
  commit_all({&out, report_out ? &*report_out : nullptr, pack_out ? &*pack_out : nullptr});
  if (!o.quiet)
    std::fprintf(stderr, "stf fit: %s size %d in %.3g s, %lld bytes (table %lld bytes) -> %s\n", o.model.c_str(),
                 report.chosen_size, report.fit_time_s, (long long)model.packed_bytes(),
                 (long long)(std::int64_t(table.alpha_bins) * table.cells * 4), o.output.c_str());
}

struct EvalOptions {
  std::string candidate, reference, json, cells;
};

// `stf eval --cells`: the candidate's exit distribution in the reference's layout, with the
// reference's alpha edges and grid, so that it can be compared or plotted cell by cell. Staged
// in the output's temporary file; run_eval commits it with the JSON.
void write_cells(AtomicOutput& out, const EvalOptions& o, const Table& reference, const std::vector<double>& joint) {
  std::string bytes;
  try {
    bytes = minimal_table_file(reference, joint, [&](H5::H5File& file) {
      h5::put_attr(file, "format", std::string("stf-cells"));
      h5::put_attr(file, "format_version", 1);
      h5::put_attr(file, "candidate", o.candidate);
      h5::put_attr(file, "reference", o.reference);
      h5::put_attr(file, "grid", reference.grid);
    }, "probability");
  } catch (const std::runtime_error& e) {
    fail("--cells: cannot write '" + o.cells + "': " + e.what());
  }
  out.stage(bytes);
}

void run_eval(const EvalOptions& o) {
  const std::vector<NamedFile> inputs{{o.candidate, "the candidate"}, {o.reference, "--reference"}};
  std::optional<AtomicOutput> json_out, cells_out;
  if (!o.json.empty()) json_out.emplace(o.json, "--json", inputs);
  if (o.cells == "-" && (o.json.empty() || o.json == "-"))
    fail("--cells - would put the HDF5 file on stdout with the JSON; give --json a file");
  if (!o.cells.empty()) {
    std::vector<NamedFile> keep = inputs;
    if (json_out) keep.push_back(json_out->named());
    cells_out.emplace(o.cells, "--cells", keep);
  }
  // A file without a format attribute may be a table stf did not make: read_table says if not.
  std::string format = fit::file_format(o.candidate);
  if (format != "stf-model" && format != "stf-table" && !format.empty())
    fail("'" + o.candidate + "' is neither an stf model nor an stf table");
  Table reference = read_table(o.reference);
  measure::Evaluation ev;
  std::vector<double> joint;
  std::vector<double>* keep_joint = cells_out ? &joint : nullptr;
  try {
    ev = format == "stf-model"
             ? measure::evaluate(fit::read_model(o.candidate), reference, fit::read_chi2_dof(o.candidate), keep_joint)
             : measure::evaluate(read_table(o.candidate), reference, keep_joint);
  } catch (const std::invalid_argument& e) {
    fail(std::string("--reference: ") + e.what());
  }
  if (cells_out) write_cells(*cells_out, o, reference, joint);
  std::string json = measure::to_json(ev);
  if (json_out) json_out->stage(json);
  else std::fputs(json.c_str(), stdout);
  commit_all({json_out ? &*json_out : nullptr, cells_out ? &*cells_out : nullptr});  // both or neither
  std::fprintf(stderr, "stf eval: tv %.4g (joint %.4g), kl %.4g%s\n", ev.tv, ev.joint_tv, ev.kl,
               ev.model_bytes >= 0 ? (", " + std::to_string(ev.model_bytes) + " model bytes").c_str() : "");
}

}  // namespace

void add_fit_options(CLI::App& cmd, std::string& model, std::string& threads) {
  cmd.add_option("--model", model, "auto (what scenes and render use: hvmf:auto), vmf:K, vmf:auto, hvmf:K, hvmf:auto, lvmf:K, lvmf:auto, sh:L or sh:auto")
      ->capture_default_str();
  cmd.add_option("--threads", threads, "Worker threads (0: all cores)")->capture_default_str();
}

fit::FitSettings fit_settings(const std::string& model, const std::string& threads) {
  fit::FitSettings settings;
  try {
    settings = fit::parse_model_spec(model);
  } catch (const std::invalid_argument& e) {
    fail(e.what());
  }
  settings.run.threads = int(parse_count(threads, "--threads", 0, 4096));
  return settings;
}

void add_fit_command(CLI::App& app) {
  auto o = std::make_shared<FitOptions>();
  CLI::App* cmd = app.add_subcommand("fit", "Fit a raw table with vMF lobes or smoothed spherical harmonics");
  cmd->add_option("table", o->table, "Raw table (HDF5)")->required()->check(CLI::ExistingFile);
  add_fit_options(*cmd, o->model, o->threads);
  cmd->add_option("-o,--output", o->output, "Output model (HDF5)")->required();
  cmd->add_option("--report", o->report, "Per-bin diagnostics and model selection as JSON");
  cmd->add_option("--pack", o->pack, "Also write the model as a binary pack for the sampler");
  cmd->add_option("--alpha-degree", o->alpha_degree,
                  "sh: store each coefficient as a Chebyshev series of this degree in cos(alpha)")
      ->capture_default_str();
  cmd->add_option("--ablate", o->ablate,
                  "Fit without the named mechanisms (comma separated: mirror, pooling, wide-pools, alpha-smoothing, "
                  "tilt, turn, blend, blend-by-bin); for measuring what each is worth (docs/fit.md, \"Ablation\")")
      ->group("Developer");
  cmd->add_option("--tolerance", o->tolerance,
                  "Target TV distance: fewest alpha bins, coarsest grid and smallest size that are certified within it");
  cmd->add_option("--heldout", o->heldout, "With --tolerance: an independent table (other seed) that certifies the fit")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--quiet", o->quiet, "No status line and no summary line");
  cmd->callback([o, cmd] { run_fit(*o, *cmd); });
}

void add_eval_command(CLI::App& app) {
  auto o = std::make_shared<EvalOptions>();
  CLI::App* cmd = app.add_subcommand("eval", "Error of a model or a raw table against a reference table");
  cmd->add_option("candidate", o->candidate, "Model or raw table (HDF5)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--reference", o->reference, "Reference table (HDF5), same alpha bins")->required()->check(CLI::ExistingFile);
  cmd->add_option("--json", o->json, "Write the JSON here instead of stdout");
  cmd->add_option("--cells", o->cells,
                  "Also write the candidate's exit distribution binned in the reference's layout (HDF5)");
  cmd->callback([o] { run_eval(*o); });
}

}  // namespace stf::cli
