// `stf pack`: models into one binary pack; `stf sample`: draw from a model, or evaluate its pdf.
#include <CLI/CLI.hpp>
#include <H5Cpp.h>

#include <cstdio>
#include <memory>

#include "cli.h"
#include "stf/core/h5io.h"
#include "stf/fit/model_io.h"
#include "stf/pack.h"
#include "stf/sampler.h"

namespace stf::cli {

namespace {

// A model from an stf-model HDF5 file or the first entry of a pack.
StfModel load_model(const std::string& path) {
  try {
    return fit::read_model_or_pack(path);
  } catch (const std::runtime_error& e) {
    fail(e.what());
  }
}

struct PackOptions {
  std::vector<std::string> models, names;
  std::string output;
};

void run_pack(const PackOptions& o) {
  if (!o.names.empty() && o.names.size() != o.models.size()) fail("--name must be given once per model or not at all");
  std::vector<NamedFile> inputs;
  for (const std::string& m : o.models) inputs.push_back({m, "model"});
  require_files(inputs);
  AtomicOutput out(o.output, "-o", inputs);
  std::vector<PackEntry> entries;
  for (std::size_t i = 0; i < o.models.size(); ++i) {
    if (fit::file_format(o.models[i]) != "stf-model") fail("'" + o.models[i] + "' is not an stf model");
    entries.push_back({o.names.empty() ? "" : o.names[i], fit::read_model(o.models[i])});
    if (o.names.empty()) entries.back().name = medium_name(entries.back().model.albedo, entries.back().model.g);
    if (!entries.back().model.has_medium())
      fail("'" + o.models[i] + "' carries no medium (its table named none), and a pack needs one (tau, albedo, g): "
           "import the histogram with --sigma-s, --sigma-a and --g and fit it again");
    if (std::string why = pack_entry_error(entries.back()); !why.empty())
      fail("'" + o.models[i] + "' cannot go into a pack: " + why);
    for (std::size_t j = 0; j < i; ++j) {
      const StfModel &a = entries[j].model, &b = entries[i].model;
      if (entries[j].name == entries[i].name && a.tau == b.tau && a.albedo == b.albedo && a.g == b.g)
        fail("'" + o.models[j] + "' and '" + o.models[i] + "' are models of one medium under one name ('" +
             entries[i].name + "'); a renderer could not tell them apart: give each its own --name");
    }
  }
  if (std::string why = pack_entries_error(entries); !why.empty()) fail("--name: " + why);
  write_file(out, write_pack(entries));
}

struct SampleOptions {
  std::string model, output, eval;
  std::string count = "1e4", seed = "1";
};

// `component` (which part drew each sample: 0 smooth, 1 uncollided, 2 once scattered) only for
// drawn samples.
void write_samples(AtomicOutput& out, const std::vector<double>& point, const std::vector<double>& direction,
                   const std::vector<double>& pdf, const std::vector<std::int8_t>& component, double escape) {
  H5::Exception::dontPrint();
  h5::MemoryFile memory;
  h5::put_attr(memory.file(), "escape_probability", escape);
  {
    H5::Group g = memory.file().createGroup("/samples");
    const hsize_t n = pdf.size();
    h5::put_dataset(g, "exit_point", {n, 3}, point.data());
    h5::put_dataset(g, "exit_direction", {n, 3}, direction.data());
    h5::put_dataset(g, "pdf", {n}, pdf.data());
    if (!component.empty()) h5::put_dataset(g, "component", {n}, component.data());
  }
  out.write(memory.bytes());
}

// Exit points and directions of a samples file (`stf sample -o` layout) for --eval.
void read_points(const std::string& path, std::vector<double>& p, std::vector<double>& d) {
  try {
    H5::Exception::dontPrint();
    h5::ReadingInput reading;
    H5::H5File in = h5::open_file(path);
    for (const char* name : {"/samples/exit_point", "/samples/exit_direction"})
      if (!h5::has_object(in, name))
        fail("--eval: '" + path + "' has no " + name + " (it needs the layout of `stf sample -o`)");
    const std::vector<hsize_t> shape = h5::dataset_shape(in, "/samples/exit_point");
    if (shape.size() != 2 || shape[1] != 3) fail("--eval: '" + path + "': /samples/exit_point must be [N, 3]");
    p = h5::get_dataset(in, "/samples/exit_point", shape);
    d = h5::get_dataset(in, "/samples/exit_direction", shape);
  } catch (const H5::Exception& e) {
    fail("--eval: cannot read '" + path + "' as HDF5: " + e.getDetailMsg());
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    fail("--eval: '" + path + "': " + std::string(e.what()));
  }
  if (p.size() != d.size() || p.size() % 3 != 0) fail("--eval: exit_point and exit_direction must both be [N, 3]");
}

void run_sample(const SampleOptions& o, const CLI::App& cmd) {
  if (!o.eval.empty() && cmd.count("--count")) fail("--count and --eval exclude each other: --eval evaluates given points");
  if (!o.eval.empty() && cmd.count("--seed")) fail("--seed and --eval exclude each other: --eval draws nothing");
  // Every sample is held in memory (about 120 bytes with its file image) until the file is written.
  const std::int64_t n = parse_count(o.count, "--count", 1, 50'000'000);
  const std::uint64_t seed = std::uint64_t(parse_count(o.seed, "--seed", 0, INT64_MAX));
  AtomicOutput out(o.output, "-o", {{o.model, "the model"}, {o.eval, "--eval"}});
  ShellSampler sampler(load_model(o.model));
  std::vector<double> point, direction, pdf;
  if (!o.eval.empty()) {
    read_points(o.eval, point, direction);
    for (std::size_t i = 0; i < point.size(); i += 3) {
      Vec3 y{point[i], point[i + 1], point[i + 2]}, w{direction[i], direction[i + 1], direction[i + 2]};
      bool unit = std::abs(length(y) - 1) < 1e-6 && std::abs(length(w) - 1) < 1e-6;
      pdf.push_back(unit ? sampler.pdf(y, w) : 0.0);  // off the domain: no support
      if (i % (3 << 16) == 0) stop_if_interrupted();
    }
    write_samples(out, point, direction, pdf, {}, sampler.escape_probability());
    return;
  }
  SampleStream stream(seed, 0);
  std::vector<std::int8_t> component;
  point.reserve(3 * std::size_t(n)), direction.reserve(3 * std::size_t(n)), pdf.reserve(std::size_t(n));
  component.reserve(std::size_t(n));
  for (std::int64_t i = 0; i < n; ++i) {
    if (i % (1 << 16) == 0) stop_if_interrupted();
    const ExitSample s = stream.next(sampler);
    point.insert(point.end(), {s.point.x, s.point.y, s.point.z});
    direction.insert(direction.end(), {s.direction.x, s.direction.y, s.direction.z});
    pdf.push_back(s.pdf);
    component.push_back(std::int8_t(s.component));
  }
  write_samples(out, point, direction, pdf, component, sampler.escape_probability());
}

}  // namespace

void add_pack_command(CLI::App& app) {
  auto o = std::make_shared<PackOptions>();
  CLI::App* cmd = app.add_subcommand("pack", "Pack fitted models into one compact binary file for the sampler");
  cmd->add_option("models", o->models, "Fitted models (HDF5)")->required();
  cmd->add_option("--name", o->names, "A name per model (default: its medium, \"albedo A g G\"); one name stands for one medium");
  cmd->add_option("-o,--output", o->output, "Output pack")->required();
  cmd->callback([o] { run_pack(*o); });
}

void add_sample_command(CLI::App& app) {
  auto o = std::make_shared<SampleOptions>();
  CLI::App* cmd = app.add_subcommand("sample", "Draw exit points and directions from a model, or evaluate its pdf");
  cmd->add_option("model", o->model, "Fitted model (HDF5) or pack")->required()->check(CLI::ExistingFile);
  cmd->add_option("--count", o->count, "Samples to draw")->capture_default_str();
  cmd->add_option("--seed", o->seed, "Random seed")->capture_default_str();
  cmd->add_option("--eval", o->eval, "Evaluate the pdf at /samples/exit_point, /samples/exit_direction of this file")
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", o->output, "Output samples (HDF5)")->required();
  cmd->callback([o, cmd] { run_sample(*o, *cmd); });
}

}  // namespace stf::cli
