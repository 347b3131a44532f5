#pragma once
// The one config struct of a replay (docs/config.md lists every key with its "why"). Loaded from
// one table for both the TOML file and `--set key=value`, then validated as a whole with the
// offending field named (Intel SFS's TileUpdateManagerDesc is the model: defaulted fields, one line
// of why each).
#include <cstdint>
#include <string>
#include <vector>

#include "core/config_table.h"
#include "stream/exec/device_model.h"
#include "stream/exec/fault_layer.h"
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

struct ReplayConfig {
  // [run]
  std::string system = "clipmap";        // clipmap | vt
  double fps = 60.0;                      // frames per second the trace is resampled to; 0 = trace's own times
  // [texture]
  std::int64_t width = 1 << 20;           // level-0 texels (8192 m at 128 texels/m)
  std::int64_t height = 1 << 20;          // level-0 texels
  double texels_per_m = 128.0;            // ground texel density at level 0
  double origin_x_m = 0.0;                // world x of texel u = 0
  double origin_y_m = 0.0;                // world y of texel v = 0
  int tile_size = 128;                    // tile payload, texels per side
  int border = 0;                         // tile border, texels per side (stored T + 2B)
  std::string layers = "albedo:rgba8";    // name:format[:compression ratio], comma separated
  // [scene]
  std::string scene = "plane";            // plane | heightfield | town | mesh
  std::string scene_file;                 // heightfield image or OBJ file (heightfield/mesh)
  double height_scale_m = 200.0;          // heightfield: metres for a full-range sample
  // [view]
  int divisor = 8;                        // feedback buffer = screen / divisor per axis
  double lod_bias = 0.0;                  // added to every desired LOD
  bool anisotropic = false;               // anisotropic LOD rule instead of max of lengths
  double max_aniso = 16.0;                // anisotropy clamp
  int popin_divisor = 0;                  // pop-in measurement buffer divisor; 0 = the feedback buffer
  int feedback_every = 1;                 // render feedback every k frames (1 = every frame)
  int render_threads = -1;                // threads rendering feedback ahead of the loop; 0 = the loop renders; -1 = auto
  double near_m = 0.05;                   // near clip, m
  double far_m = 1.0e7;                   // far clip, m
  // [clipmap]
  int clipsize = 1024;                    // N: stack window side, texels
  double update_threshold_tiles = 0.5;    // hysteresis before a window recentres, tiles
  int invalid_border_tiles = 0;           // window edge tiles excluded from sampling
  int filter_margin_texels = 1;           // footprint half-width that must be valid
  // [vt] (virtual texturing; texture.tile_size is the page payload P, texture.border the border B)
  std::int64_t vt_pool_pages = 1024;      // physical page pool, slots (RAGE-like: a 4096² texture of 128² pages)
  int vt_locked_levels = 1;               // coarsest levels locked resident (never evicted)
  int vt_prefetch_finer_levels = 0;       // also fetch pages 1 or 2 levels finer into RAM (Unreal); 0 = off
  int vt_residency_window_frames = 15;    // a page used within this many frames counts as visible
  // [ram]
  double ram_MiB = 256.0;                 // RAM cache of decoded tiles, MiB
  // [prefetch]
  double prefetch_lookahead_s = 0.0;      // look-ahead along the motion, seconds; 0 = off
  // [disk] (-1 = from the preset)
  std::string disk_preset = "nvme";       // hdd | sata_ssd | nvme | optical | unconstrained
  double disk_latency_us = -1.0;
  double disk_bandwidth_MBps = -1.0;
  int disk_channels = -1;
  // [decode]
  double decode_throughput_MBps = 0.0;    // per worker, decoded MB/s; 0 = free
  double decode_per_tile_us = 0.0;        // fixed cost per tile, us
  int decode_workers = 2;                 // decode threads (0 = unlimited)
  // [upload]
  int upload_tiles_per_frame = 16;        // tiles per frame; -1 = no tile limit
  std::int64_t upload_bytes_per_frame = -1;  // bytes per frame; -1 = no byte limit
  double upload_link_MBps = 12000.0;      // host -> VRAM link; 0 = unlimited
  // [io]
  int max_in_flight = 64;                 // jobs given to the executor at once (IO pool bound)
  int max_retries = 2;                    // retries of a faulted tile
  int retry_backoff_frames = 2;           // frames before a retry
  int io_threads = 4;                     // real clock: IO pool workers (reads in flight at once)
  bool io_direct = true;                  // real clock: O_DIRECT reads (fallback with a warning)
  double fault_rate = 0.0;                // probability a read fails with EIO (both clocks)
  std::int64_t fault_seed = 1;            // seed of the deterministic fault pattern
  double fault_short_read_rate = 0.0;     // probability a read comes back short
  double fault_checksum_rate = 0.0;       // probability a read's payload arrives corrupted
  double fault_slow_rate = 0.0;           // probability a read is slow ...
  double fault_slow_ms = 50.0;            // ... by this much, ms
  // [throttle]
  std::string throttle = "deadline";      // none | deadline | ... (stream/throttle/throttle_registry.cpp)
  double deadline_ms = 250.0;
  double relax_factor = 0.5;
  int relax_frames = 15;
  double drain_horizon_s = 1.0;           // an over-deadline backlog that drains slower than this outruns
  double high_water = 0.95;               // VT policies: pool pressure/occupancy above which the bias rises
  double low_water = 0.75;                // ... below which it falls
  double bias_step = 0.25;                // RAGE: bias change per adjustment, levels
  double max_bias = 4.0;                  // bias clamp, levels
  double adjust_rate = 0.2;               // Unreal: bias change per unit of residency beyond a bound
  // [metrics]
  double cut_m = 50.0;                    // a frame-to-frame jump longer than this is a cut
  double turn_deg_per_s = 180.0;          // faster rotation is a fast turn
  double sharp_margin = 0.01;             // sharp again: blurry fraction <= baseline + this
  int thrash_frames = 60;                 // evicted then needed within this many frames = thrash

  // Derived (filled by validate()).
  std::vector<LayerSpec> layer_specs;
  DiskModel disk;
  DecodeModel decode;
  UploadModel upload;
  ThrottleParams throttle_params;
  FaultConfig faults;
};

const ConfigTable<ReplayConfig>& replay_config_table();

// Cross-field checks and derived values; throws InputError naming the field ("clipmap.clipsize").
void validate(ReplayConfig& c);

// The effective config: defaults, then the TOML file (if any), then `system` (if not empty), then
// each "key=value" of `sets` in order; validated. Throws InputError naming the file/line or key.
ReplayConfig load_replay_config(const std::string& config_path, const std::vector<std::string>& sets,
                                const std::string& system = "");

// Bytes of one tile of a layer in RAM/VRAM (payload plus border) and on disk.
std::uint64_t tile_decoded_bytes(const ReplayConfig& c, const LayerSpec& layer);
std::uint64_t tile_disk_bytes(const ReplayConfig& c, const LayerSpec& layer);

}  // namespace vtsim
