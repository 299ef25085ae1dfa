// `stf`: the command line over the stf stages.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>

#include "cli.h"
#include "mpi.h"

namespace {

// --config files may spell keys as scene files do (alpha_bins) or as the command line does
// (alpha-bins); both name the same option.
class ConfigWithUnderscores : public CLI::ConfigTOML {
 public:
  std::vector<CLI::ConfigItem> from_config(std::istream& input) const override {
    std::vector<CLI::ConfigItem> items = CLI::ConfigTOML::from_config(input);
    for (CLI::ConfigItem& item : items) std::replace(item.name.begin(), item.name.end(), '_', '-');
    return items;
  }
};

// An empty value ('' on the command line, "" in a --config file) would convert to 0 for a
// number and to nothing for a path; no option of stf takes one.
void refuse_empty_values(CLI::App& app) {
  const CLI::Validator non_empty([](std::string& v) { return v.empty() ? std::string("got an empty value") : std::string(); },
                                 "");
  for (CLI::App* command : app.get_subcommands([](CLI::App*) { return true; }))
    for (CLI::Option* option : command->get_options())
      if (option->get_type_size() != 0 && !option->get_lnames().empty() && option->get_lnames().front() != "help" &&
          option->get_lnames().front() != "name")  // pack --name '': an entry without a name
        option->check(non_empty);
}

// The subcommand a command line names (the first word that is not an option or --config's
// value), or "" when there is none.
std::string command_word(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--config") ++i;
    else if (!a.empty() && a[0] != '-') return a;
  }
  return "";
}

// What the command line asks that stf refuses before CLI11 parses it: an unknown command, and
// under mpirun a command that does not share its work across ranks (each rank would do all of
// it and write the same output). Ranks run the same command (check_same_command_on_every_rank).
void check_command(CLI::App& app, int argc, char** argv) {
  const std::string word = command_word(argc, argv);
  if (word.empty()) return;
  std::string names;
  bool known = false;
  for (CLI::App* c : app.get_subcommands([](CLI::App*) { return true; })) {
    names += (names.empty() ? "" : ", ") + c->get_name();
    known = known || c->get_name() == word;
  }
  if (!known) stf::cli::fail("unknown command '" + word + "'; the commands are " + names);
  if (stf::cli::world().size > 1 && word != "precompute" && word != "build")
    stf::cli::fail("stf " + word + " runs as one process: under mpirun only precompute and build share their work across ranks");
}

// One command line, parsed and run; returns the exit status.
int run(int argc, char** argv) {
  CLI::App app("stf: shell transport functions for rendering dense media");
  app.require_subcommand(1);
  app.set_version_flag("--version", "stf " STF_VERSION);
  // Options may come from a TOML file, one [section] per subcommand (data/default_medium.toml).
  app.set_config("--config", "", "Read options from a TOML file, [subcommand] sections");
  app.config_formatter(std::make_shared<ConfigWithUnderscores>());
  app.allow_config_extras(CLI::config_extras_mode::error);  // an unknown key is an error, not ignored
  stf::cli::add_precompute_command(app);
  stf::cli::add_merge_command(app);
  stf::cli::add_fit_command(app);
  stf::cli::add_eval_command(app);
  stf::cli::add_import_command(app);
  stf::cli::add_smooth_command(app);
  stf::cli::add_pack_command(app);
  stf::cli::add_sample_command(app);
  stf::cli::add_build_command(app);
  stf::cli::add_report_command(app);
  stf::cli::add_plot_command(app);
  stf::cli::add_render_command(app);
  stf::cli::add_mesh_command(app);
  stf::cli::add_grid_command(app);
  refuse_empty_values(app);
  // From the start: Ctrl-C during any stage stops it cleanly (stages poll the flag).
  stf::cli::install_interrupt_handler();
  try {
    stf::cli::check_config_syntax(argc, argv);
    check_command(app, argc, argv);
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ConfigError& e) {
    const std::string what = e.what(), prefix = "INI was not able to parse ";
    if (what.rfind(prefix, 0) == 0)
      std::fprintf(stderr, "stf: error: --config: unknown key '%s'\n", what.substr(prefix.size()).c_str());
    else
      std::fprintf(stderr, "stf: error: --config: %s\n", what.c_str());
    return 2;
  } catch (const stf::cli::Interrupted& e) {
    if (stf::cli::world().root()) std::fprintf(stderr, "stf: %s\n", e.what());
    return stf::cli::interrupted_status();
  } catch (const stf::cli::ToleranceNotMet& e) {
    if (stf::cli::world().root()) std::fprintf(stderr, "stf: error: %s\n", e.what());
    return 3;
  } catch (const std::bad_alloc&) {
    if (stf::cli::world().root()) std::fprintf(stderr, "stf: error: out of memory; nothing written\n");
    return 2;
  } catch (const std::exception& e) {
    // CLI11's parse errors, stf's own user errors and failures of a stage alike: one line,
    // once (every MPI rank meets the same bad input; a rank's own failure is reported by
    // on_every_rank).
    if (stf::cli::world().root()) std::fprintf(stderr, "stf: error: %s\n", e.what());
    return 2;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  stf::cli::start_mpi(argc, argv);  // a no-op unless mpirun started this process
  if (!stf::cli::same_command_on_every_rank(argc, argv)) {
    if (stf::cli::world().root())
      std::fprintf(stderr, "stf: error: the MPI ranks were started with different command lines; every rank must run the same command\n");
    stf::cli::finish_mpi();
    return 2;
  }
  int status = run(argc, argv);
  stf::cli::finish_mpi();
  return status;
}
