#pragma once
// How every command reads a replay config (docs/config.md): -c/--config FILE, repeatable, read in
// order ("-": stdin), then each --set key=value; one loader and one wording for replay, view and
// capacity. Commands whose own flags set config values let a flag the user gave win over the
// config, and the config over the flag's default (flags_given).
#include <set>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "cli/cli_io.h"
#include "sim/run/replay_config.h"

namespace vtsim::cli {

// stdin_taken: another option reads stdin ("--trace -"), so "--config -" cannot.
inline ReplayConfig load_cli_config(const std::vector<std::string>& configs, const std::vector<std::string>& sets,
                                    const std::string& system = "", bool stdin_taken = false) {
  return with_inputs(configs, "--config", stdin_taken,
                     [&](const std::vector<std::string>& p) { return load_replay_config(p, sets, system); });
}

// -c/--config and --set on `c`; `note` ends their help (what the command reads of the config).
inline void add_config_options(CLI::App* c, std::vector<std::string>& configs, std::vector<std::string>& sets,
                               const std::string& note = "") {
  c->add_option("--config,-c", configs,
                "TOML config file (docs/config.md; - for stdin); repeatable: files read in order, a later one "
                "overriding an earlier one's keys" + note)
      ->allow_extra_args(false);
  c->add_option("--set", sets, "override one config key (repeatable)" + note);
}

// The long names of `c`'s options the command line gave ("--divisor").
inline std::set<std::string> flags_given(const CLI::App* c) {
  std::set<std::string> given;
  for (const CLI::Option* o : c->get_options())
    if (o->count() > 0 && !o->get_lnames().empty()) given.insert("--" + o->get_lnames().front());
  return given;
}

}  // namespace vtsim::cli
