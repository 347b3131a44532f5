#pragma once
// Replays against a real tile store (docs/real-engine.md): the store decides the texture, its
// index gives every tile's disk and decoded bytes (in both clocks), and the real clock runs the
// frame loop against a ThreadedExecutor paced in wall-clock time, copying uploads into a VRAM
// arena. The simulated clock with the same store and a calibrated device profile predicts it.
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "sim/run/replay.h"
#include "stream/store/tile_store.h"
#include "cache/vram_arena.h"
#include "stream/produce/terrain_producer.h"

namespace vtsim {

// Makes the config's texture the store's: texture.width, .height, .tile_size, .border and .layers
// left at their defaults are taken from the store header (formats from the channel counts,
// compression ratios from the index); a value that differs from both the default and the store is
// rejected with InputError naming the field. Re-validates, then checks that the store holds every
// level the system uses (clipmap: all, down to 1×1; VT: down to a single page). Returns notes
// saying what was taken from the store.
std::vector<std::string> bind_store_texture(ReplayConfig& cfg, const TileStore& store);

// Per-tile sizes from the store's index: disk bytes = the aligned read (what crosses the disk under
// O_DIRECT), decoded bytes = the tile. Keys outside the store cost nothing.
TileSizer store_sizer(const TileStore& store);

// Plays a trace `speed` times faster (times divided by speed; the config's frame rate multiplied),
// so both clocks see the same faster camera. Throws InputError("--speed") outside (0, 1000].
void apply_speed(ReplayConfig& cfg, Trace& trace, double speed);

class TimelineRecorder;

struct RealClockOptions {
  std::function<void(int, int)> progress;  // as ReplayEnv::progress
  // Bytes of host memory the RAM cache's buffers and the VRAM arena may take together; 0: what
  // this process may use (usable_memory_bytes). Tests set a small one.
  std::uint64_t memory_limit_bytes = 0;
  // The terrain: keep every composed tile's work and time (RealRun::produced_tiles), for
  // `vtsim calibrate --samples` (docs/produced.md, "Calibrating from the replay's own tiles").
  bool record_produced_tiles = false;
  // Non-null: every tile request's stages, with wall times (`--timeline`, timeline.h).
  TimelineRecorder* timeline = nullptr;
};

struct RealRun {
  ReplayResult result;               // the summary has a "real_clock" section
  std::unique_ptr<VramArena> arena;  // what the uploads copied, for inspection
  // Virtual texturing: the pages complete in the pool when the replay ended, with their slots
  // (what the page table maps, so what sampling would read from the arena).
  std::vector<std::pair<TileKey, std::uint32_t>> pool_pages;
  // The terrain with RealClockOptions::record_produced_tiles: every tile composed, in completion order.
  std::vector<produce::ProducedTile> produced_tiles;
};

// Runs the trace in the real clock: IO and decode threads (io.threads, decode.workers,
// io.max_in_flight, io.direct, io.fault*), frames paced to the trace's times in wall time, uploads
// copied into the VRAM arena (clipmap: its windows; VT: the physical page pool, each page in the
// slot the system gave it). `cfg` must have been bound to `store` (bind_store_texture).
// Checks what the real clock can run before anything is read (the CLI calls it first): a stored
// system needs a store (InputError "--store"); the terrain (its tiles produced, its brush mips
// served from memory: docs/produced.md, "The real clock") takes none (InputError "--store" if
// given), rgba8 layers only (field texture.layers) and 1..1024 production threads (field
// produce.workers).
void check_real_clock_system(const ReplayConfig& cfg, bool have_store);
// True for a system whose tiles the real clock produces instead of reading (the terrain).
bool produced_system(const ReplayConfig& cfg);
// The TerrainProducer's figures from the config's [texture] and [terrain] sections.
produce::TerrainProducerParams terrain_producer_params(const ReplayConfig& cfg);

RealRun run_real_replay(const ReplayConfig& cfg, const Trace& trace, const IScene& scene, const TileStore& store,
                        const RealClockOptions& options = {});
// The terrain in the real clock, without a store: produce.workers production threads run a
// TerrainProducer (stream/produce/terrain_producer.h) composing every produced tile and serving
// the brush mips; the VRAM arena is sized from the config's layers. The summary's real_clock has
// a "producer" section (tiles composed, brush mips served).
RealRun run_real_replay(const ReplayConfig& cfg, const Trace& trace, const IScene& scene, const RealClockOptions& options = {});

}  // namespace vtsim
