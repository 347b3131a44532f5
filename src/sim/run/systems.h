#pragma once
// The streaming systems a replay can run (run.system), one line each in systems.cpp. A system is
// a class in src/stream/system/ behind IStreamingSystem with its own config section; its entry
// here is made from the class's static members (system_entry below), so adding a system is its
// file, its section in ReplayConfig with the section's keys, and one line in the table.
#include <cstdint>
#include <memory>
#include <string_view>
#include <vector>

#include "cache/vram_arena.h"
#include "core/registry.h"
#include "sim/run/replay_config.h"
#include "stream/system/i_system.h"
#include "stream/system/system_caps.h"

namespace vtsim {

struct SystemInfo {
  std::string_view name;
  std::string_view why;
  // Cross-field checks of the system's section against the rest; throws InputError naming the field.
  void (*validate)(const ReplayConfig& c);
  // The system over a texture of `extent` (the scene's).
  std::unique_ptr<IStreamingSystem> (*make)(const ReplayConfig& c, TextureExtent extent);
  // The levels a tile store must hold for it, and why, for the message when it holds fewer.
  int (*store_levels)(const ReplayConfig& c);
  std::string_view store_levels_why;
  // The real clock's VRAM arena for it, and the config field that sizes it (for the message when
  // it does not fit). Throws VramArena::ArenaTooLarge.
  VramArena (*vram_arena)(const ReplayConfig& c, std::vector<std::uint32_t> layer_bytes, std::uint64_t host_limit);
  std::string_view vram_field;
  // What it can do (stream/system/system_caps.h): asked instead of its name.
  SystemCaps caps;
};

const Registry<SystemInfo>& streaming_systems();

// What every system is built from, from the config: the texture (extent: the scene's; by default
// the config's texture.width × height), its layers, the ground mapping and the run's settings.
SystemSetup system_setup(const ReplayConfig& c);
SystemSetup system_setup(const ReplayConfig& c, TextureExtent extent);

// The system c.run.system names over a texture of `extent`.
std::unique_ptr<IStreamingSystem> make_system(const ReplayConfig& c, TextureExtent extent);

// A table entry from a system class S and its section of ReplayConfig: S::Config, a constructor
// S(const SystemSetup&, const S::Config&), and static validate, store_levels, kStoreLevels,
// vram_arena, kVramField, kName and kCaps (see stream/system/clipmap_system.h).
template <class S, typename S::Config ReplayConfig::*Section>
SystemInfo system_entry(std::string_view why) {
  return {S::kName,
          why,
          [](const ReplayConfig& c) { S::validate(system_setup(c), c.*Section, c.throttle); },
          [](const ReplayConfig& c, TextureExtent extent) -> std::unique_ptr<IStreamingSystem> {
            return std::make_unique<S>(system_setup(c, extent), c.*Section);
          },
          [](const ReplayConfig& c) { return S::store_levels(system_setup(c), c.*Section); },
          S::kStoreLevels,
          [](const ReplayConfig& c, std::vector<std::uint32_t> layer_bytes, std::uint64_t host_limit) {
            return S::vram_arena(system_setup(c), c.*Section, std::move(layer_bytes), host_limit);
          },
          S::kVramField,
          S::kCaps};
}

// A table entry for a system whose windows read the [clipmap] section besides its own (the terrain):
// a constructor S(const SystemSetup&, const ClipmapConfig&, const S::Config&) and
// validate(setup, clipmap, section, throttle); store_levels and vram_arena take [clipmap].
template <class S, typename S::Config ReplayConfig::*Section>
SystemInfo clipmap_system_entry(std::string_view why) {
  return {S::kName,
          why,
          [](const ReplayConfig& c) { S::validate(system_setup(c), c.clipmap, c.*Section, c.throttle); },
          [](const ReplayConfig& c, TextureExtent extent) -> std::unique_ptr<IStreamingSystem> {
            return std::make_unique<S>(system_setup(c, extent), c.clipmap, c.*Section);
          },
          [](const ReplayConfig& c) { return S::store_levels(system_setup(c), c.clipmap); },
          S::kStoreLevels,
          [](const ReplayConfig& c, std::vector<std::uint32_t> layer_bytes, std::uint64_t host_limit) {
            return S::vram_arena(system_setup(c), c.clipmap, std::move(layer_bytes), host_limit);
          },
          S::kVramField,
          S::kCaps};
}

}  // namespace vtsim
