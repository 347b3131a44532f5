// Replay configs: a TOML file (the first part of the input) and --set assignments (the lines of
// the part after a 0xFF byte), loaded as `vtsim replay --config F --set ...` loads them. An
// accepted config then builds its scene and system and replays four frames of a small static
// trace in the simulated clock: validation at load must refuse whatever the replay cannot run.
#include <memory>
#include <string>
#include <vector>

#include "fuzz_targets.h"
#include "sim/run/replay.h"
#include "sim/run/replay_config.h"
#include "sim/view/scene.h"
#include "sim/trace/trace_transform.h"

namespace vtsim::fuzz {

void config(const std::uint8_t* data, std::size_t size) {
  // Not a structured binding: clang 14 cannot capture one in a lambda.
  const auto parts = split2(data, size);
  const std::string_view toml = parts.first, set_text = parts.second;
  std::vector<std::string> sets;
  for (std::size_t a = 0; a < set_text.size();) {
    std::size_t b = set_text.find('\n', a);
    if (b == std::string_view::npos) b = set_text.size();
    sets.emplace_back(set_text.substr(a, b - a));
    a = b + 1;
  }
  ReplayConfig cfg;
  std::unique_ptr<IScene> scene;
  expect_accept_or_reject("config", [&] {
    const std::string path = input_file(reinterpret_cast<const std::uint8_t*>(toml.data()), toml.size(), "toml");
    cfg = load_replay_config(path, sets);
    scene = make_scene_from_config(cfg);  // may refuse: files, texture size against the scene
  });
  if (!scene) return;
  must_succeed("config", "the replay of a validated config", [&] {
    Trace t;
    t.image_width = 64;
    t.image_height = 36;
    for (int k = 0; k < 4; ++k) {
      Pose p;
      p.t_s = k / 60.0;
      p.pos_m = {100.0, 100.0, 30.0};
      p.q = yaw_pitch_quat(30.0, -20.0);
      t.poses.push_back(p);
    }
    (void)run_replay(cfg, t, *scene);
  });
}

}  // namespace vtsim::fuzz
