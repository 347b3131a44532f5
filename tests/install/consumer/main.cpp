// Embeds vtsim: replays a trace with a config through the library API, then checks that every
// section of its summary equals the one the CLI wrote for the same trace and config (apart from
// what measures this process: run.* wall time). Usage: vtsim_consumer TRACE CLI_SUMMARY.json [KEY=VALUE...]
#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "sim/run/replay.h"
#include "sim/trace/trace_import.h"
#include "sim/view/scene.h"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::cerr << "usage: vtsim_consumer TRACE CLI_SUMMARY.json [KEY=VALUE...]\n";
    return 2;
  }
  try {
    const std::vector<std::string> sets(argv + 3, argv + argc);
    const vtsim::ReplayConfig cfg = vtsim::load_replay_config("", sets);
    const vtsim::Trace trace = vtsim::load_any_trace(argv[1]);
    const std::unique_ptr<vtsim::IScene> scene = vtsim::make_scene_from_config(cfg);
    const vtsim::ReplayResult r = vtsim::run_replay(cfg, trace, *scene);

    std::ifstream in(argv[2]);
    const nlohmann::json cli = nlohmann::json::parse(in);
    int same = 0, differ = 0;
    for (const auto& [section, value] : r.summary.items()) {
      if (section == "run") continue;  // wall-clock cost of this process
      const auto it = cli.find(section);
      if (it == cli.end() || *it != value) {
        std::cerr << "vtsim_consumer: section '" << section << "' differs from the CLI's\n";
        ++differ;
      } else {
        ++same;
      }
    }
    std::cout << "vtsim_consumer: " << trace.poses.size() << " poses; " << same << " summary sections equal the CLI's, "
              << differ << " differ\n";
    return differ == 0 && same > 0 ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "vtsim_consumer: error: " << e.what() << "\n";
    return 1;
  }
}
