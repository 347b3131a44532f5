#include "sim/run/replay_config.h"

#include "cache/page_table.h"
#include "core/tile_key.h"

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace vtsim {

namespace {

struct FormatInfo {
  const char* name;
  double bytes_per_texel;
};
// Block-compressed formats store 4×4 texel blocks of 8 (BC1, BC4) or 16 bytes (BC3, BC5, BC7).
constexpr FormatInfo kFormats[] = {
    {"rgba8", 4.0}, {"rgb8", 3.0}, {"rg8", 2.0}, {"r8", 1.0}, {"rgba16f", 8.0},
    {"bc1", 0.5},   {"bc4", 0.5},  {"bc3", 1.0}, {"bc5", 1.0}, {"bc7", 1.0},
};

void check_one_of(const std::string& v, std::initializer_list<const char*> options) {
  std::string list;
  for (const char* o : options) {
    if (v == o) return;
    list += list.empty() ? o : std::string(", ") + o;
  }
  throw std::invalid_argument("'" + v + "' is not one of: " + list);
}

}  // namespace

std::vector<LayerSpec> parse_layers(const std::string& spec) {
  std::vector<LayerSpec> out;
  std::size_t start = 0;
  while (start <= spec.size()) {
    const std::size_t comma = spec.find(',', start);
    std::string part = spec.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    start = comma == std::string::npos ? spec.size() + 1 : comma + 1;
    const auto b = part.find_first_not_of(" \t"), e = part.find_last_not_of(" \t");
    if (b == std::string::npos) throw std::invalid_argument("empty layer in '" + spec + "'");
    part = part.substr(b, e - b + 1);
    std::vector<std::string> f;
    std::size_t s = 0;
    for (;;) {
      const std::size_t c = part.find(':', s);
      f.push_back(part.substr(s, c == std::string::npos ? std::string::npos : c - s));
      if (c == std::string::npos) break;
      s = c + 1;
    }
    if (f.size() < 2 || f.size() > 3 || f[0].empty())
      throw std::invalid_argument("layer '" + part + "': expected name:format[:compression_ratio]");
    LayerSpec L;
    L.name = f[0];
    L.format = f[1];
    bool known = false;
    for (const auto& fi : kFormats)
      if (f[1] == fi.name) L.bytes_per_texel = fi.bytes_per_texel, known = true;
    if (!known)
      throw std::invalid_argument("layer '" + part + "': unknown format '" + f[1] +
                                  "' (rgba8, rgb8, rg8, r8, rgba16f, bc1, bc3, bc4, bc5, bc7)");
    if (f.size() == 3) {
      std::size_t pos = 0;
      double r = 0;
      try {
        r = std::stod(f[2], &pos);
      } catch (const std::exception&) {
        pos = 0;
      }
      if (pos != f[2].size() || !(r >= 1.0 && r <= 1000.0))
        throw std::invalid_argument("layer '" + part + "': compression ratio must be a number in [1, 1000]");
      L.compression_ratio = r;
    }
    for (const auto& other : out)
      if (other.name == L.name) throw std::invalid_argument("layer name '" + L.name + "' appears twice");
    out.push_back(L);
  }
  if (out.size() > 16) throw std::invalid_argument("at most 16 layers");
  return out;
}

const ConfigTable<ReplayConfig>& replay_config_table() {
  using C = ReplayConfig;
  static const ConfigTable<C> table = [] {
    ConfigTable<C> t;
    constexpr double kInf = std::numeric_limits<double>::max();
    t.add(cfg::text<C>("run.system", &C::system, [](const std::string& v) { check_one_of(v, {"clipmap", "vt"}); },
                       "streaming system: clipmap | vt"))
        .add(cfg::real<C>("run.fps", &C::fps, 0.0, 1000.0, "trace resampled to this frame rate, Hz; 0 = the trace's own times"))
        .add(cfg::integer<C>("texture.width", &C::width, 1, std::int64_t{1} << 34, "level-0 width, texels (any size, not only 2^k)"))
        .add(cfg::integer<C>("texture.height", &C::height, 1, std::int64_t{1} << 34, "level-0 height, texels"))
        .add(cfg::real<C>("texture.texels_per_m", &C::texels_per_m, 1e-6, 1e6, "ground texel density at level 0, texels/m"))
        .add(cfg::real<C>("texture.origin_x_m", &C::origin_x_m, -1e12, 1e12, "world x of texel column 0, m"))
        .add(cfg::real<C>("texture.origin_y_m", &C::origin_y_m, -1e12, 1e12, "world y of texel row 0, m"))
        .add(cfg::integer<C>("texture.tile_size", &C::tile_size, 8, 1 << 16,
                             "tile payload, texels a side (>= 8: smaller tiles are no streaming unit, and millions of them a frame)"))
        .add(cfg::integer<C>("texture.border", &C::border, 0, 1 << 10, "tile border, texels a side (stored T+2B)"))
        .add(cfg::text<C>("texture.layers", &C::layers, [](const std::string& v) { parse_layers(v); },
                          "layers as name:format[:compression ratio], comma separated"))
        .add(cfg::text<C>("scene.kind", &C::scene,
                          [](const std::string& v) { check_one_of(v, {"plane", "heightfield", "town", "mesh"}); },
                          "scene: plane | heightfield | town | mesh"))
        .add(cfg::text<C>("scene.file", &C::scene_file, nullptr, "heightfield image or OBJ mesh (heightfield, mesh)"))
        .add(cfg::real<C>("scene.height_scale_m", &C::height_scale_m, 0.0, 1e5, "heightfield: metres for full-range heights"))
        .add(cfg::integer<C>("view.divisor", &C::divisor, 1, 256, "feedback buffer = screen / divisor per axis (speed/error knob)"))
        .add(cfg::real<C>("view.lod_bias", &C::lod_bias, -16.0, 16.0, "added to every desired LOD, levels"))
        .add(cfg::boolean<C>("view.anisotropic", &C::anisotropic, "anisotropic LOD rule instead of max of lengths"))
        .add(cfg::real<C>("view.max_aniso", &C::max_aniso, 1.0, 64.0, "anisotropy clamp of the anisotropic rule"))
        .add(cfg::integer<C>("view.popin_divisor", &C::popin_divisor, 0, 256, "pop-in buffer divisor; 0 = the feedback buffer"))
        .add(cfg::integer<C>("view.feedback_every", &C::feedback_every, 1, 1000, "render feedback every k frames"))
        .add(cfg::integer<C>("view.render_threads", &C::render_threads, -1, 64,
                             "threads rendering feedback ahead of the frame loop, same results; 0 = the loop renders "
                             "(one core); -1 = auto (one per core up to 8; sim clock only)"))
        .add(cfg::real<C>("view.near_m", &C::near_m, 1e-6, 1e6, "near clip, m"))
        .add(cfg::real<C>("view.far_m", &C::far_m, 1e-3, 1e12, "far clip, m"))
        .add(cfg::integer<C>("clipmap.clipsize", &C::clipsize, 1, 1 << 20, "N: clip stack window side, texels (multiple of the tile)"))
        .add(cfg::real<C>("clipmap.update_threshold_tiles", &C::update_threshold_tiles, 0.0, 64.0,
                          "hysteresis before a window recentres, tiles (Unity Clipmap UpdateThreshold)"))
        .add(cfg::integer<C>("clipmap.invalid_border_tiles", &C::invalid_border_tiles, 0, 1 << 10,
                             "window edge tiles excluded from sampling (Yao 2007 §4-6)"))
        .add(cfg::integer<C>("clipmap.filter_margin_texels", &C::filter_margin_texels, 0, 64,
                             "footprint half-width that must be valid (bilinear: 1)"))
        .add(cfg::integer<C>("vt.pool_pages", &C::vt_pool_pages, 1, std::int64_t{1} << 24,
                             "physical page pool, slots of one page in every layer (the VRAM budget)"))
        .add(cfg::integer<C>("vt.locked_levels", &C::vt_locked_levels, 0, 63,
                             "coarsest levels locked resident: the fallback every sample has"))
        .add(cfg::integer<C>("vt.prefetch_finer_levels", &C::vt_prefetch_finer_levels, 0, 2,
                             "also fetch pages 1 or 2 levels finer than desired into RAM (Unreal); 0 = off"))
        .add(cfg::integer<C>("vt.residency_window_frames", &C::vt_residency_window_frames, 1, 100000,
                             "a page used within this many frames counts as visible (pool occupancy)"))
        .add(cfg::real<C>("ram.capacity_MiB", &C::ram_MiB, 0.0, 1e9, "RAM cache of decoded tiles, MiB (hard cap)"))
        .add(cfg::real<C>("prefetch.lookahead_s", &C::prefetch_lookahead_s, 0.0, 3600.0,
                          "look-ahead along the motion (Yao 2007 §4-2), s; 0 = off"))
        .add(cfg::text<C>("disk.preset", &C::disk_preset,
                          [](const std::string& v) {
                            if (!find_disk_preset(v)) check_one_of(v, {"hdd", "sata_ssd", "nvme", "optical", "unconstrained"});
                          },
                          "disk model preset: hdd | sata_ssd | nvme | optical | unconstrained"))
        .add(cfg::real<C>("disk.latency_us", &C::disk_latency_us, -1.0, 1e9, "per-request latency, us; -1 = preset"))
        .add(cfg::real<C>("disk.bandwidth_MBps", &C::disk_bandwidth_MBps, -1.0, 1e9,
                          "transfer bandwidth, MB/s; 0 = unlimited; -1 = preset"))
        .add(cfg::integer<C>("disk.channels", &C::disk_channels, -1, 1 << 16, "requests in service at once; 0 = unlimited; -1 = preset"))
        .add(cfg::real<C>("decode.throughput_MBps", &C::decode_throughput_MBps, 0.0, kInf, "decoded MB/s per worker; 0 = free"))
        .add(cfg::real<C>("decode.per_tile_us", &C::decode_per_tile_us, 0.0, 1e9, "fixed decode cost per tile, us"))
        .add(cfg::integer<C>("decode.workers", &C::decode_workers, 0, 1024, "decode workers; 0 = unlimited"))
        .add(cfg::integer<C>("upload.tiles_per_frame", &C::upload_tiles_per_frame, -1, 1 << 20,
                             "upload budget, tiles per frame; -1 = no tile limit (0 is rejected)"))
        .add(cfg::integer<C>("upload.bytes_per_frame", &C::upload_bytes_per_frame, -1, std::int64_t{1} << 40,
                             "upload budget, bytes per frame; -1 = no byte limit (0 is rejected)"))
        .add(cfg::real<C>("upload.link_MBps", &C::upload_link_MBps, 0.0, kInf, "host to VRAM link, MB/s; 0 = unlimited"))
        .add(cfg::integer<C>("io.max_in_flight", &C::max_in_flight, 1, 1 << 20, "jobs submitted to the IO/decode executor at once"))
        .add(cfg::integer<C>("io.max_retries", &C::max_retries, 0, 100, "retries of a faulted tile before it fails"))
        .add(cfg::integer<C>("io.retry_backoff_frames", &C::retry_backoff_frames, 0, 100000, "frames before a retry"))
        .add(cfg::integer<C>("io.threads", &C::io_threads, 1, 256,
                             "real clock: IO pool threads, = reads in flight at once (Yao 2007 §4-3)"))
        .add(cfg::boolean<C>("io.direct", &C::io_direct, "real clock: unbuffered O_DIRECT reads (Yao 2007 §4-3); false = page cache"))
        .add(cfg::real<C>("io.fault_rate", &C::fault_rate, 0.0, 1.0, "probability that a read fails with EIO (injected, both clocks)"))
        .add(cfg::integer<C>("io.fault_seed", &C::fault_seed, 0, std::numeric_limits<std::int64_t>::max(),
                             "seed of the injected fault pattern (per tile and attempt)"))
        .add(cfg::real<C>("io.fault.short_read_rate", &C::fault_short_read_rate, 0.0, 1.0,
                          "probability that a read returns half its record (injected short read)"))
        .add(cfg::real<C>("io.fault.checksum_rate", &C::fault_checksum_rate, 0.0, 1.0,
                          "probability that a read's payload arrives corrupted (caught by the checksum)"))
        .add(cfg::real<C>("io.fault.slow_rate", &C::fault_slow_rate, 0.0, 1.0, "probability that a read is slow (io.fault.slow_ms more)"))
        .add(cfg::real<C>("io.fault.slow_ms", &C::fault_slow_ms, 0.0, 60000.0, "extra time of a slow read, ms"))
        .add(cfg::text<C>("throttle.policy", &C::throttle,
                          [](const std::string& v) {
                            if (make_throttle_policy(v, ThrottleParams{})) return;
                            std::string names;
                            for (const auto& p : throttle_policies()) names += (names.empty() ? "" : ", ") + std::string(p.name);
                            throw std::invalid_argument("unknown policy '" + v + "' (one of: " + names + ")");
                          },
                          "MaxTextureLOD/residency policy (stream/throttle/throttle_registry.cpp)"))
        .add(cfg::real<C>("throttle.deadline_ms", &C::deadline_ms, 0.001, 1e7, "clamp levels whose backlog takes longer, ms"))
        .add(cfg::real<C>("throttle.relax_factor", &C::relax_factor, 0.0, 1.0, "relax when the finer backlog fits deadline × this"))
        .add(cfg::integer<C>("throttle.relax_frames", &C::relax_frames, 1, 100000, "... for this many consecutive frames"))
        .add(cfg::real<C>("throttle.drain_horizon_s", &C::drain_horizon_s, 0.0, 1e6,
                          "an over-deadline backlog not back under it within this long clamps, s"))
        .add(cfg::real<C>("throttle.high_water", &C::high_water, 0.0, 100.0,
                          "VT: pool pressure (RAGE) / visible residency (Unreal) above which the bias rises"))
        .add(cfg::real<C>("throttle.low_water", &C::low_water, 0.0, 100.0, "VT: ... below which the bias falls"))
        .add(cfg::real<C>("throttle.bias_step", &C::bias_step, 0.0, 16.0, "RAGE: feedback bias change per adjustment, levels"))
        .add(cfg::real<C>("throttle.max_bias", &C::max_bias, 0.0, 16.0, "VT: largest feedback bias, levels"))
        .add(cfg::real<C>("throttle.adjust_rate", &C::adjust_rate, 0.0, 100.0,
                          "Unreal: bias change per frame per unit of residency beyond a bound"))
        .add(cfg::real<C>("metrics.cut_m", &C::cut_m, 0.0, 1e12, "a frame-to-frame jump longer than this is a cut, m"))
        .add(cfg::real<C>("metrics.turn_deg_per_s", &C::turn_deg_per_s, 0.0, 1e6, "faster rotation is a fast turn, deg/s"))
        .add(cfg::real<C>("metrics.sharp_margin", &C::sharp_margin, 0.0, 1.0,
                          "sharp again when blurry fraction <= pre-event baseline + this"))
        .add(cfg::integer<C>("metrics.thrash_frames", &C::thrash_frames, 1, 1 << 20, "evicted then needed within this many frames = thrash"));
    return t;
  }();
  return table;
}

std::uint64_t tile_decoded_bytes(const ReplayConfig& c, const LayerSpec& layer) {
  const double side = static_cast<double>(c.tile_size + 2 * c.border);
  return static_cast<std::uint64_t>(std::ceil(side * side * layer.bytes_per_texel));
}

std::uint64_t tile_disk_bytes(const ReplayConfig& c, const LayerSpec& layer) {
  return static_cast<std::uint64_t>(std::ceil(static_cast<double>(tile_decoded_bytes(c, layer)) / layer.compression_ratio));
}

[[noreturn]] static void bad(const std::string& key, const std::string& what) {
  throw InputError("config", "field '" + key + "': " + what);
}

// Largest clip window side in tiles: 256² tiles a level is already far beyond any engine's window
// (RAGE-style clipmaps keep 8-32 tiles a side), and a frame tracks every tile of every window.
constexpr int kMaxClipTiles = 256;
// Least resampling rate: a frame every 100 s (slower, a trace would replay its first frame only).
constexpr double kMinFps = 0.01;
// Least bandwidth or throughput the simulated clock accepts: below it one tile's transfer time
// leaves the 64-bit nanosecond clock's range (1 KB/s moves a 1 MB tile in 1,000 s).
constexpr double kMinRateMBps = 1e-3;

void validate(ReplayConfig& c) {
  try {
    c.layer_specs = parse_layers(c.layers);
  } catch (const std::invalid_argument& e) {
    bad("texture.layers", e.what());
  }
  // 0 means the trace's own times; a rate that slow (a subnormal one) would replay frame 0 only.
  if (c.fps != 0.0 && c.fps < kMinFps)
    bad("run.fps", fmt::format("{:g} Hz is below {:g} Hz (0 replays the trace's own times)", c.fps, kMinFps));
  if (c.system == "clipmap") {
    if (c.clipsize % c.tile_size != 0)
      bad("clipmap.clipsize", fmt::format("{} is not a multiple of texture.tile_size {}", c.clipsize, c.tile_size));
    // A window is (clipsize / tile)² tiles per level, all tracked every frame.
    if (c.clipsize / c.tile_size > kMaxClipTiles)
      bad("clipmap.clipsize", fmt::format("{} is more than {} tiles of {} texels a side: use larger tiles", c.clipsize,
                                          kMaxClipTiles, c.tile_size));
    if (c.border != 0 && c.system == "clipmap")
      bad("texture.border", "the clipmap's toroidal windows keep neighbours adjacent: borders must be 0");
  }
  if (c.system == "vt") {
    if (c.tile_size < 2 || c.tile_size % 2 != 0)
      bad("texture.tile_size", fmt::format("{}: a VT page must be even (a page lies inside one parent page)", c.tile_size));
    if (c.border > c.tile_size)
      bad("texture.border", fmt::format("{} texels is larger than the page ({} texels)", c.border, c.tile_size));
    // Partial edge pages are allowed (docs/vt.md): no divisibility check on texture.width/height.
    try {
      const VtGeometry g({c.width, c.height}, c.tile_size, c.border);
      if (c.vt_locked_levels > g.levels())
        bad("vt.locked_levels", fmt::format("{} is more than the texture's {} levels", c.vt_locked_levels, g.levels()));
      const std::uint64_t locked = g.coarsest_pages(c.vt_locked_levels);
      if (static_cast<std::uint64_t>(c.vt_pool_pages) < locked)
        bad("vt.pool_pages", fmt::format("{} pages is smaller than the {} locked levels ({} pages)", c.vt_pool_pages,
                                         c.vt_locked_levels, locked));
    } catch (const std::invalid_argument& e) {
      bad("texture.tile_size", e.what());
    }
    if (c.low_water > c.high_water)
      bad("throttle.low_water", fmt::format("{} is above throttle.high_water {}", c.low_water, c.high_water));
  }
  if (c.upload_tiles_per_frame == 0)
    bad("upload.tiles_per_frame", "a zero budget uploads nothing; use -1 for no tile limit");
  if (c.upload_bytes_per_frame == 0)
    bad("upload.bytes_per_frame", "a zero budget uploads nothing; use -1 for no byte limit");
  std::uint64_t max_tile = 0;
  for (const auto& L : c.layer_specs) max_tile = std::max(max_tile, tile_decoded_bytes(c, L));
  if (c.upload_bytes_per_frame > 0 && static_cast<std::uint64_t>(c.upload_bytes_per_frame) < max_tile)
    bad("upload.bytes_per_frame", fmt::format("{} bytes is smaller than one tile ({} bytes): nothing could upload",
                                              c.upload_bytes_per_frame, max_tile));
  const double ram_bytes = c.ram_MiB * 1048576.0;
  if (ram_bytes < static_cast<double>(max_tile))
    bad("ram.capacity_MiB", fmt::format("{} MiB is smaller than one tile ({} bytes)", c.ram_MiB, max_tile));
  if (c.far_m <= c.near_m) bad("view.far_m", "must be greater than view.near_m");
  const auto rate = [](const char* key, double v) {
    if (v > 0.0 && v < kMinRateMBps)
      bad(key, fmt::format("{} MB/s is below {} MB/s (one tile would take longer than the clock can count)", v, kMinRateMBps));
  };
  rate("disk.bandwidth_MBps", c.disk_bandwidth_MBps);
  rate("decode.throughput_MBps", c.decode_throughput_MBps);
  rate("upload.link_MBps", c.upload_link_MBps);
  if (c.scene == "mesh" && c.scene_file.empty()) bad("scene.file", "scene.kind = \"mesh\" needs an OBJ file");
  const std::int64_t max_side = std::max(c.width, c.height);
  if (max_side / c.tile_size > TileKey::kMaxCoord)
    bad("texture.tile_size", "too many tiles a side for the 27-bit tile coordinates: use larger tiles");

  const DevicePreset* preset = find_disk_preset(c.disk_preset);
  if (!preset) bad("disk.preset", "unknown preset '" + c.disk_preset + "'");
  c.disk = preset->disk;
  if (c.disk_latency_us >= 0) c.disk.latency_us = c.disk_latency_us;
  if (c.disk_bandwidth_MBps >= 0) c.disk.bandwidth_MBps = c.disk_bandwidth_MBps;
  if (c.disk_channels >= 0) c.disk.channels = c.disk_channels;
  c.decode = DecodeModel{c.decode_throughput_MBps, c.decode_per_tile_us, c.decode_workers};
  c.upload.tiles_per_frame = c.upload_tiles_per_frame < 0 ? 0 : c.upload_tiles_per_frame;
  c.upload.bytes_per_frame = c.upload_bytes_per_frame < 0 ? 0 : static_cast<std::uint64_t>(c.upload_bytes_per_frame);
  c.upload.link_MBps = c.upload_link_MBps;
  c.faults = FaultConfig{c.fault_rate,          static_cast<std::uint64_t>(c.fault_seed), c.fault_short_read_rate,
                         c.fault_checksum_rate, c.fault_slow_rate, c.fault_slow_ms};
  c.throttle_params = ThrottleParams{};
  c.throttle_params.deadline_ms = c.deadline_ms;
  c.throttle_params.relax_factor = c.relax_factor;
  c.throttle_params.relax_frames = c.relax_frames;
  c.throttle_params.drain_horizon_s = c.drain_horizon_s;
  c.throttle_params.high_water = c.high_water;
  c.throttle_params.low_water = c.low_water;
  c.throttle_params.bias_step = c.bias_step;
  c.throttle_params.max_bias = c.max_bias;
  c.throttle_params.adjust_rate = c.adjust_rate;
}

}  // namespace vtsim

namespace vtsim {

ReplayConfig load_replay_config(const std::string& config_path, const std::vector<std::string>& sets,
                                const std::string& system) {
  ReplayConfig cfg;
  const auto& table = replay_config_table();
  if (!config_path.empty()) load_toml_file(table, cfg, config_path);
  if (!system.empty()) table.set(cfg, "run.system", ConfigValue{system}, "--system");
  for (const auto& s : sets) apply_set(table, cfg, s);
  validate(cfg);
  return cfg;
}

}  // namespace vtsim
