#include "fuzz_targets.h"

namespace vtsim::fuzz {

const std::vector<Target>& targets() {
  static const std::vector<Target> all = {
      {"trace_native", trace_native}, {"trace_import", trace_import}, {"config", config},
      {"compare", compare},           {"store", store},               {"obj", obj},
      {"store_replay", store_replay}, {"image", image}, {"sweep_spec", sweep_spec},
      {"access_file", access_file}, {"mesh_import", mesh_import}, {"q3_entities", q3_entities}, {"feedback", feedback},
      {"cachesim_formats", cachesim_formats},
  };
  return all;
}

const Target* find_target(std::string_view name) {
  for (const Target& t : targets())
    if (name == t.name) return &t;
  return nullptr;
}

}  // namespace vtsim::fuzz
