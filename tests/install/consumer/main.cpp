// Embeds vtsim: replays a trace with a config through the library API, then checks that every
// section of its summary equals the one the CLI wrote for the same trace and config (apart from
// what measures this process: run.* wall time); then streams as an engine would, through the
// streaming runtime (docs/embedding.md, "Streaming from an engine"), until the pages it asks for
// are mapped. Usage: vtsim_consumer TRACE CLI_SUMMARY.json [KEY=VALUE...]
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "sim/run/replay.h"
#include "sim/run/runtime_setup.h"
#include "sim/trace/trace_import.h"
#include "sim/view/scene.h"

namespace {

// The engine's GPU: its copy of each tile (here: counted) and its page table.
class Gpu final : public vtsim::IUploadSink {
 public:
  void upload(const vtsim::TileUpload& u) override { ++uploads; (void)u.data; }  // glTexSubImage2D at u.slot
  int uploads = 0;
  std::map<std::uint64_t, std::int64_t> page_table;  // page key -> pool slot
};

// An engine's frames against the runtime (simulated executor: no store needed); true when every
// page it asked for is mapped.
bool engine_frames(std::vector<std::string> sets) {
  sets.push_back("run.system=vt");
  const vtsim::ReplayConfig cfg = vtsim::load_replay_config("", sets);
  vtsim::StreamingRuntime rt(vtsim::runtime_parts(cfg, {cfg.texture.width, cfg.texture.height}, 1.0 / 60, nullptr, nullptr));
  Gpu gpu;
  const vtsim::TileKey want[] = {vtsim::TileKey(0, 2, 5, 7), vtsim::TileKey(0, 2, 6, 7), vtsim::TileKey(0, 4, 1, 1)};
  for (int frame = 0; frame < 20; ++frame) {
    rt.begin_frame(vtsim::seconds_to_ticks(frame / 60.0));
    for (const vtsim::TileKey& k : want) rt.request(k);  // what the feedback pass saw
    const vtsim::FrameUpdates& u = rt.end_frame(gpu);    // gpu.upload(...) per tile, in the budget
    for (const vtsim::PageTableUpdate& p : u.page_table) {
      if (p.slot < 0) gpu.page_table.erase(p.page.bits);
      else gpu.page_table[p.page.bits] = p.slot;
    }
    // ... then set MaxTextureLOD to u.clamp and the LOD bias to u.sample_bias, and draw.
  }
  int mapped = 0;
  for (const vtsim::TileKey& k : want) mapped += gpu.page_table.count(k.bits) ? 1 : 0;
  std::cout << "vtsim_consumer: runtime: " << gpu.uploads << " uploads, " << mapped << " of 3 requested pages mapped\n";
  return mapped == 3;
}

}  // namespace

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
    const bool streamed = engine_frames(sets);
    return differ == 0 && same > 0 && streamed ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "vtsim_consumer: error: " << e.what() << "\n";
    return 1;
  }
}
