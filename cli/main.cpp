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
  stf::cli::add_pack_command(app);
  stf::cli::add_sample_command(app);
  stf::cli::add_build_command(app);
  stf::cli::add_report_command(app);
  stf::cli::add_plot_command(app);
  stf::cli::add_render_command(app);
  // From the start: Ctrl-C during any stage stops it cleanly (stages poll the flag).
  stf::cli::install_interrupt_handler();
  try {
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
    std::fprintf(stderr, "stf: %s\n", e.what());
    return 130;
  } catch (const stf::cli::ToleranceNotMet& e) {
    std::fprintf(stderr, "stf: error: %s\n", e.what());
    return 3;
  } catch (const std::exception& e) {
    // CLI11's parse errors, stf's own user errors and failures of a stage alike: one line.
    std::fprintf(stderr, "stf: error: %s\n", e.what());
    return 2;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  stf::cli::start_mpi(argc, argv);  // a no-op unless mpirun started this process
  int status = run(argc, argv);
  stf::cli::finish_mpi();
  return status;
}
