#pragma once
// Each command family lives in its own cmd_*.cpp and registers its subcommands here.
// Exit codes (README.md, "What else it does"): 0 success; 1 the command ran and found a failure
// (a regression in `vtsim compare`, tiles that failed in a replay with --fail-on-error); 2 bad
// input or usage (the message names the file, line or field); 3 internal error (a bug: please
// report it).
#include <CLI/CLI.hpp>

namespace vtsim::cli {

inline constexpr int kExitOk = 0, kExitFailure = 1, kExitBadInput = 2, kExitInternal = 3;

// Thrown by a command callback to end the program with a given exit code (after printing).
struct Exit {
  int code;
};

// Thrown by `vtsim help CMD...`: main prints that command's help (the same as `vtsim CMD... --help`).
struct HelpFor {
  const CLI::App* app;
  std::string prev;  // the program and parent commands, as CLI::App::help() takes them
};

void register_trace_commands(CLI::App& app);
void register_capacity_commands(CLI::App& app);
void register_replay_commands(CLI::App& app);
void register_view_commands(CLI::App& app);
void register_store_commands(CLI::App& app);
void register_calibrate_commands(CLI::App& app);
void register_compare_commands(CLI::App& app);
void register_vt_commands(CLI::App& app);
void register_sweep_commands(CLI::App& app);
void register_tune_commands(CLI::App& app);
void register_mrc_commands(CLI::App& app);
void register_cachesim_commands(CLI::App& app);
void register_report_commands(CLI::App& app);
void register_atlas_commands(CLI::App& app);
void register_gl_commands(CLI::App& app);
// `vtsim gl calibrate-upload` (cmd_gl_calibrate.cpp), under `gl`.
void register_gl_calibrate_command(CLI::App& gl);
// `vtsim help [CMD...]` and `vtsim completion bash`, generated from the commands registered before.
void register_help_commands(CLI::App& app);
// The bash completion script for `app`'s commands and options (every subcommand, every flag).
std::string bash_completion(const CLI::App& app);

}  // namespace vtsim::cli
