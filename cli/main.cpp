// `stf`: the command line over the stf stages.
#include <CLI/CLI.hpp>

#include <cstdio>

#include "cli.h"

int main(int argc, char** argv) {
  CLI::App app("stf: shell transport functions for rendering dense media");
  app.require_subcommand(1);
  app.set_version_flag("--version", "stf " STF_VERSION);
  // Options may come from a TOML file, one [section] per subcommand (data/default_medium.toml).
  app.set_config("--config", "", "Read options from a TOML file, [subcommand] sections");
  stf::cli::add_precompute_command(app);
  stf::cli::add_fit_command(app);
  stf::cli::add_eval_command(app);
  stf::cli::add_pack_command(app);
  stf::cli::add_sample_command(app);
  stf::cli::add_build_command(app);
  stf::cli::add_report_command(app);
  stf::cli::add_plot_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    // CLI11's parse errors, stf's own user errors and failures of a stage alike: one line.
    std::fprintf(stderr, "stf: error: %s\n", e.what());
    return 2;
  }
  return 0;
}
