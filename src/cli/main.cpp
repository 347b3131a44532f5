// vtsim: thin command-line front end over vtsim_lib. Parsing and printing only; the work is in
// the library so that engines can embed it.
#include <fmt/core.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <iostream>
#include <string>

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

}  // namespace

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
  vtsim::cli::register_sweep_commands(app);
  vtsim::cli::register_tune_commands(app);
  vtsim::cli::register_mrc_commands(app);
  vtsim::cli::register_report_commands(app);
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
    if (std::ferror(stdout)) return stdout_failed();  // fmt::print threw on a full or closed stdout
    fmt::print(stderr, "vtsim: internal error: {}\n", e.what());
    return vtsim::cli::kExitInternal;
  }
  // Output still in the buffers is written here: a full disk or a closed pipe shows only now.
  std::cout.flush();
  if (!std::cout || std::fflush(stdout) != 0 || std::ferror(stdout)) return stdout_failed();
  return vtsim::cli::kExitOk;
}
