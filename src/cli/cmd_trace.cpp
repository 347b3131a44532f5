// vtsim trace …: generate, import, inspect camera traces (docs/traces.md).
#include "cli/commands.h"

namespace vtsim::cli {

void register_trace_commands(CLI::App& app) {
  auto* trace = app.add_subcommand("trace", "Generate, import, resample and inspect camera traces");
  trace->require_subcommand(1);
}

}  // namespace vtsim::cli
