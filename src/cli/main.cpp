// vtsim: thin command-line front end over vtsim_lib. Parsing and printing only; the work is in
// the library so that engines can embed it.
#include <fmt/core.h>

#include <cstdio>
#include <exception>

#include "cli/commands.h"
#include "core/error.h"

int main(int argc, char** argv) {
  CLI::App app{"vtsim — asynchronous texture-streaming engine and cache-hierarchy simulator"};
  app.set_version_flag("--version", std::string("vtsim ") + VTSIM_VERSION);
  app.require_subcommand(1);
  vtsim::cli::register_trace_commands(app);
  vtsim::cli::register_capacity_commands(app);
  vtsim::cli::register_replay_commands(app);
  vtsim::cli::register_view_commands(app);
  vtsim::cli::register_store_commands(app);
  vtsim::cli::register_calibrate_commands(app);
  vtsim::cli::register_compare_commands(app);
  vtsim::cli::register_vt_commands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return vtsim::cli::kExitBadInput;
  } catch (const vtsim::cli::Exit& e) {
    return e.code;
  } catch (const vtsim::InputError& e) {
    fmt::print(stderr, "vtsim: error: {}\n", e.what());
    return vtsim::cli::kExitBadInput;
  } catch (const std::exception& e) {
    fmt::print(stderr, "vtsim: internal error: {}\n", e.what());
    return vtsim::cli::kExitInternal;
  }
  return vtsim::cli::kExitOk;
}
