// vtsim: thin command-line front end over vtsim_lib. Parsing and printing only; the work is in
// the library so that engines can embed it.
#include <fmt/core.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <iostream>
#include <string>

#include "cli/cli_io.h"
#include "cli/commands.h"
#include "core/error.h"

namespace {

// What a command printed did not all reach stdout (> /dev/full, a closed pipe): an error, not a
// success with the summary lost.
int stdout_failed() {
  const int err = errno;
  fmt::print(stderr, "vtsim: error: stdout: write failed{}\n", err ? std::string(": ") + std::strerror(err) : "");
  return vtsim::cli::kExitBadInput;
}

// CLI11's usage errors in the program's own form: "vtsim: error: ..." and where to read more.
std::string main_failure_message(const CLI::App* app, const CLI::Error& e) {
  std::string name;  // the command the user typed, as far as it was parsed
  for (const CLI::App* a = app; a && !a->get_subcommands().empty();) {
    a = a->get_subcommands().front();
    name += a->get_name() + " ";
  }
  return fmt::format("vtsim: error: {}\nRun `vtsim {}--help` for more information.\n", e.what(), name);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"vtsim — asynchronous texture-streaming engine and cache-hierarchy simulator"};
  app.set_version_flag("--version", std::string("vtsim ") + VTSIM_VERSION);
  app.require_subcommand(1);
  // Global flags may follow the subcommand too (`vtsim replay ... --werror`).
  app.fallthrough();
  bool werror = false;
  app.add_flag("--werror", werror, "treat warnings as errors: exit 1 if any warning was printed (-q never hides warnings)");
  app.failure_message(main_failure_message);
  vtsim::cli::register_trace_commands(app);
  vtsim::cli::register_capacity_commands(app);
  vtsim::cli::register_replay_commands(app);
  vtsim::cli::register_view_commands(app);
  vtsim::cli::register_store_commands(app);
  vtsim::cli::register_calibrate_commands(app);
  vtsim::cli::register_compare_commands(app);
  vtsim::cli::register_vt_commands(app);
  vtsim::cli::register_sweep_commands(app);
  vtsim::cli::register_tune_commands(app);
  vtsim::cli::register_mrc_commands(app);
  vtsim::cli::register_cachesim_commands(app);
  vtsim::cli::register_report_commands(app);
  vtsim::cli::register_atlas_commands(app);
  vtsim::cli::register_gl_commands(app);
  vtsim::cli::register_help_commands(app);  // last: they walk the commands above
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
  } catch (const vtsim::cli::HelpFor& e) {  // `vtsim help CMD...`: as `vtsim CMD... --help`
    fmt::print("{}", e.app == &app ? app.help() : e.app->help(e.prev));
    return vtsim::cli::kExitOk;
  } catch (const vtsim::InputError& e) {
    fmt::print(stderr, "vtsim: error: {}\n", e.what());
    return vtsim::cli::kExitBadInput;
  } catch (const std::exception& e) {
    if (std::ferror(stdout)) return stdout_failed();  // fmt::print threw on a full or closed stdout
    fmt::print(stderr, "vtsim: internal error: {}\n", e.what());
    return vtsim::cli::kExitInternal;
  }
  // Output still in the buffers is written here: a full disk or a closed pipe shows only now.
  std::cout.flush();
  if (!std::cout || std::fflush(stdout) != 0 || std::ferror(stdout)) return stdout_failed();
  if (werror && vtsim::cli::warnings_printed() > 0) {
    fmt::print(stderr, "vtsim: error: {} warning{} printed and --werror given\n", vtsim::cli::warnings_printed(),
               vtsim::cli::warnings_printed() == 1 ? "" : "s");
    return vtsim::cli::kExitFailure;
  }
  return vtsim::cli::kExitOk;
}
