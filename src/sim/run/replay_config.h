#pragma once
// The one config struct of a replay (docs/config.md lists every key with its "why"). One member
// per config section ([texture], [view], [throttle], ...), each the parameter struct its room
// uses directly — ThrottleParams, FaultConfig, DecodeModel, the systems' own sections — so a key
// binds to the very member the code reads: no mirrored fields and no copying. Loaded from one
// table for both the TOML file and `--set key=value`, then validated as a whole with the offending
// field named (Intel SFS's TileUpdateManagerDesc is the model: defaulted fields, one line of why
// each; the whys live in the table, replay_config_keys.cpp).
//
// The struct and its inline helpers are data: the streaming systems' table (systems.h) reads
// them. The key table, validation and loading declared below read that table in turn, so they are
// defined above it, in replay_config_keys.cpp: the includes run one way.
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "core/config_table.h"
#include "core/view.h"
#include "sim/view/scene.h"
#include "stream/exec/device_model.h"
#include "stream/exec/fault_layer.h"
#include "stream/exec/produce.h"
#include "stream/system/clipmap_system.h"
#include "stream/system/terrain_system.h"
#include "stream/system/vt_system.h"
#include "stream/throttle/i_throttle.h"

namespace vtsim {

// A texture layer: name, texel format (bytes per texel, block formats fractional) and the disk
// codec's compression ratio (decoded bytes / disk bytes).
struct LayerSpec {
  std::string name;
  std::string format;            // rgba8, rgb8, rg8, r8, rgba16f, bc1, bc3, bc4, bc5, bc7
  double bytes_per_texel = 4.0;
  double compression_ratio = 1.0;  // 1 = raw on disk
};
// "albedo:bc7:2.5,normal:bc5" -> layers; throws std::invalid_argument naming the bad part.
std::vector<LayerSpec> parse_layers(const std::string& spec);

// texture.layers as written and as parsed: one value, set as a whole (the key's setter parses).
struct LayerList {
  std::string text = "albedo:rgba8";             // name:format[:compression ratio], comma separated
  std::vector<LayerSpec> specs = parse_layers(text);
};

struct RunConfig {
  std::string system = "clipmap";  // a name of streaming_systems() (sim/run/systems.h)
  double fps = 60.0;               // the trace is resampled to this rate; 0 = its own times
};

struct TextureConfig {
  std::int64_t width = 1 << 20;    // level-0 texels (8192 m at 128 texels/m)
  std::int64_t height = 1 << 20;
  double texels_per_m = 128.0;     // ground texel density at level 0
  double origin_x_m = 0.0;         // world x of texel u = 0
  double origin_y_m = 0.0;         // world y of texel v = 0
  int tile_size = 128;             // tile (VT: page) payload, texels a side
  int border = 0;                  // tile border, texels a side (stored T + 2B)
  LayerList layers;
};

struct ViewConfig {
  int divisor = 8;                 // feedback buffer = screen / divisor per axis
  double lod_bias = 0.0;           // added to every desired LOD, levels
  bool anisotropic = false;        // anisotropic LOD rule instead of the max of the lengths
  double max_aniso = 16.0;         // anisotropy clamp
  int popin_divisor = 0;           // pop-in measurement buffer divisor; 0 = the feedback buffer
  int feedback_every = 1;          // render feedback every k frames
  int feedback_latency = 0;        // frames between rendering feedback and acting on it (an engine's
                                   // asynchronous readback: 2–3 frames; 0 = the same frame)
  int render_threads = -1;         // threads rendering feedback ahead of the loop; 0 = the loop; -1 = auto
  double near_m = 0.05;            // near clip, m
  double far_m = 1.0e7;            // far clip, m
  std::string feedback_sampling = "middle";  // GPU model: the pixel of each feedback tile sampled, the
                                            // middle one or a per-frame sequence visiting them all
  std::string lod_model = "analytic";  // analytic: footprint per full-resolution pixel; gpu: what a GPU
                                       // feedback pass at 1/divisor requests (sim/view/gpu_model.h)
};

struct RamConfig {
  double capacity_MiB = 256.0;     // RAM cache of decoded tiles, MiB (hard cap)
  std::string policy = "lru";      // a name of replacement_policies() (cache/policy/i_replacement.h)
};

struct PrefetchConfig {
  double lookahead_s = 0.0;        // look-ahead along the motion, s; 0 = off
};

struct IoConfig {
  int max_in_flight = 64;          // jobs given to the executor at once (IO pool bound)
  int max_retries = 2;             // retries of a faulted tile
  int retry_backoff_frames = 2;    // frames before a retry
  int threads = 4;                 // real clock: IO pool workers (reads in flight at once)
  bool direct = true;              // real clock: O_DIRECT reads (fallback with a warning)
  std::string engine = "psync";    // real clock: the IO pool's engine (stream/exec/io_pool.h io_engines(); psync | io_uring)
  int queue_depth = 16;            // real clock, io_uring: reads in flight per IO thread (the ring's depth)
  FaultConfig faults{.slow_ms = 50.0};  // injected faults (io.fault_rate, io.fault.*), both clocks
};

struct MetricsConfig {
  double cut_m = 50.0;             // a frame-to-frame jump longer than this is a cut, m
  double turn_deg_per_s = 180.0;   // faster rotation is a fast turn
  double sharp_margin = 0.01;      // sharp again: blurry fraction <= baseline + this
  int thrash_frames = 60;          // evicted then needed within this many frames = thrash
  bool opt = false;                // record each cache level's accesses: Belady's bound, offline replays, miss-ratio curve
  double warmup_s = 0.0;           // the start-up fill, left out of the steady-state figures (reported in startup.*)
};

struct ReplayConfig {
  RunConfig run;
  TextureConfig texture;
  SceneConfig scene;               // sim/view/scene.h: the scene.* keys; its placement is [texture]'s (scene_config_of)
  ViewConfig view;
  ClipmapConfig clipmap;           // stream/system/clipmap_system.h
  VtConfig vt;                     // stream/system/vt_system.h
  TerrainConfig terrain;           // stream/system/terrain_system.h
  RamConfig ram;
  PrefetchConfig prefetch;
  DiskConfig disk;                 // stream/exec/device_model.h: a preset and its overrides
  DecodeModel decode;              // stream/exec/device_model.h
  UploadModel upload;              // stream/exec/device_model.h
  IoConfig io;
  ProduceModel produce;            // stream/exec/produce.h: the produce stage's cost model and budget
  ThrottleParams throttle;         // stream/throttle/i_throttle.h
  MetricsConfig metrics;
};

const ConfigTable<ReplayConfig>& replay_config_table();

// Cross-field checks (the streaming system's own, from its registry entry, and the ones between
// sections); throws InputError naming the field ("clipmap.clipsize"). Changes nothing.
void validate(const ReplayConfig& c);

// The effective config: defaults, then the TOML file (if any), then `system` (if not empty), then
// each "key=value" of `sets` in order; validated. Throws InputError naming the file/line or key.
ReplayConfig load_replay_config(const std::string& config_path, const std::vector<std::string>& sets,
                                const std::string& system = "");
// The same with several TOML files, read in order: a key a later file sets overrides an earlier
// file's (a profile, then a scene's config). Validated once, after everything.
ReplayConfig load_replay_config(const std::vector<std::string>& config_paths, const std::vector<std::string>& sets,
                                const std::string& system = "");

// docs/config.md's reference: the table of every key (default and why), then each extension
// point's table (systems, scenes, policies, disk presets, codecs) with its entries' whys.
std::string config_reference_markdown();

// Bytes of one tile of a layer in RAM/VRAM (payload plus border) and on disk.
inline std::uint64_t tile_decoded_bytes(const ReplayConfig& c, const LayerSpec& layer) {
  const double side = static_cast<double>(c.texture.tile_size + 2 * c.texture.border);
  return static_cast<std::uint64_t>(std::ceil(side * side * layer.bytes_per_texel));
}
inline std::uint64_t tile_disk_bytes(const ReplayConfig& c, const LayerSpec& layer) {
  return static_cast<std::uint64_t>(std::ceil(static_cast<double>(tile_decoded_bytes(c, layer)) / layer.compression_ratio));
}

// The view parameters the renderer takes from the [view] section (lod_bias and max_aniso as
// float, as the renderer computes them).
inline ViewParams view_params(const ViewConfig& v) {
  ViewParams p;
  p.divisor = v.divisor;
  p.lod_bias = static_cast<float>(v.lod_bias);
  p.anisotropic = v.anisotropic;
  p.max_aniso = static_cast<float>(v.max_aniso);
  p.near_m = v.near_m;
  p.far_m = v.far_m;
  return p;
}

}  // namespace vtsim
