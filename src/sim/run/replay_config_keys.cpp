#include "sim/run/replay_config.h"

#include "cache/policy/i_replacement.h"
#include "core/tile_key.h"
#include "sim/run/systems.h"
#include "sim/view/scene.h"
#include "stream/exec/io_engine.h"
#include "stream/store/i_codec.h"

#include <fmt/format.h>

#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace vtsim {

namespace {

struct FormatInfo {
  const char* name;
  double bytes_per_texel;
};
// Block-compressed formats store 4×4 texel blocks of 8 (BC1, BC4) or 16 bytes (BC3, BC5, BC7).
constexpr FormatInfo kFormats[] = {
    {"rgba8", 4.0}, {"rgb8", 3.0}, {"rg8", 2.0}, {"r8", 1.0}, {"rgba16f", 8.0},
    {"bc1", 0.5},   {"bc3", 1.0},  {"bc4", 0.5}, {"bc5", 1.0}, {"bc7", 1.0},
};

// A validator for a text field taking one of a few words (the scene.mesh_* and view.lod_model choices).
std::function<void(const std::string&)> one_of_mesh(std::vector<std::string> words) {
  return [words](const std::string& v) {
    std::string list;
    for (const std::string& w : words) {
      if (v == w) return;
      list += (list.empty() ? "\"" : ", \"") + w + "\"";
    }
    throw std::invalid_argument("'" + v + "' is not one of " + list);
  };
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
    if (!known) {
      std::string names;
      for (const auto& fi : kFormats) names += (names.empty() ? "" : ", ") + std::string(fi.name);
      throw std::invalid_argument("layer '" + part + "': unknown format '" + f[1] + "' (" + names + ")");
    }
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
  using cfg::at;
  static const ConfigTable<C> table = [] {
    ConfigTable<C> t;
    constexpr double kInf = std::numeric_limits<double>::max();
    t.add(cfg::choice<C>("run.system", at(&C::run, &RunConfig::system), streaming_systems(), "streaming system"))
        .add(cfg::real<C>("run.fps", at(&C::run, &RunConfig::fps), 0.0, 1000.0, "trace resampled to this frame rate, Hz; 0 = the trace's own times"))
        .add(cfg::integer<C>("texture.width", at(&C::texture, &TextureConfig::width), 1, std::int64_t{1} << 34, "level-0 width, texels (any size, not only 2^k)"))
        .add(cfg::integer<C>("texture.height", at(&C::texture, &TextureConfig::height), 1, std::int64_t{1} << 34, "level-0 height, texels"))
        .add(cfg::real<C>("texture.texels_per_m", at(&C::texture, &TextureConfig::texels_per_m), 1e-6, 1e6, "ground texel density at level 0, texels/m"))
        .add(cfg::real<C>("texture.origin_x_m", at(&C::texture, &TextureConfig::origin_x_m), -1e12, 1e12, "world x of texel column 0, m"))
        .add(cfg::real<C>("texture.origin_y_m", at(&C::texture, &TextureConfig::origin_y_m), -1e12, 1e12, "world y of texel row 0, m"))
        .add(cfg::integer<C>("texture.tile_size", at(&C::texture, &TextureConfig::tile_size), 8, 1 << 16,
                             "tile payload, texels a side (>= 8: smaller tiles are no streaming unit, and millions of them a frame)"))
        .add(cfg::integer<C>("texture.border", at(&C::texture, &TextureConfig::border), 0, 1 << 10, "tile border, texels a side (stored T+2B)"))
        .add({"texture.layers", "layers as name:format[:compression ratio], comma separated",
              [](C& c, const ConfigValue& v) {
                LayerList l;
                l.text = cfg::as_string(v);
                l.specs = parse_layers(l.text);
                c.texture.layers = std::move(l);
              },
              [](const C& c) { return "\"" + c.texture.layers.text + "\""; }})
        .add(cfg::choice<C>("scene.kind", at(&C::scene, &SceneConfig::kind), scenes(), "scene"))
        .add(cfg::text<C>("scene.file", at(&C::scene, &SceneConfig::file), nullptr, "heightfield image or mesh file (heightfield, mesh)"))
        .add(cfg::real<C>("scene.height_scale_m", at(&C::scene, &SceneConfig::height_scale_m), 0.0, 1e5, "heightfield: metres for full-range heights"))
        .add(cfg::text<C>("scene.mesh_loader", at(&C::scene, &SceneConfig::mesh_loader), one_of_mesh({"auto", "assimp", "obj"}),
                          "mesh: reader of scene.file: auto = the OBJ reader for .obj (vt spans the texture), assimp otherwise"))
        .add(cfg::real<C>("scene.mesh_unit_m", at(&C::scene, &SceneConfig::mesh_unit_m), 1e-9, 1e6,
                          "mesh (assimp): metres per file unit (Quake 3: 0.0254)"))
        .add(cfg::text<C>("scene.mesh_up", at(&C::scene, &SceneConfig::mesh_up), one_of_mesh({"auto", "y", "z"}),
                          "mesh (assimp): the file's up axis; auto = y for glTF/FBX/Collada, z otherwise"))
        .add(cfg::integer<C>("scene.mesh_uv_set", at(&C::scene, &SceneConfig::mesh_uv_set), 0, 7,
                             "mesh (assimp): UV channel mapped into the texture (Quake 3: 0 texture, 1 lightmap)"))
        .add(cfg::text<C>("scene.mesh_no_uv", at(&C::scene, &SceneConfig::mesh_no_uv),
                          one_of_mesh({"untextured", "skip", "planar", "error"}),
                          "mesh (assimp): parts without that UV set: untextured occluders, skip, planar projection, or error"))
        .add(cfg::real<C>("scene.mesh_planar_m", at(&C::scene, &SceneConfig::mesh_planar_m), 1e-6, 1e6,
                          "mesh (assimp), mesh_no_uv = planar: metres of world per UV period"))
        .add(cfg::integer<C>("view.divisor", at(&C::view, &ViewConfig::divisor), 1, 256, "feedback buffer = screen / divisor per axis (speed/error knob)"))
        .add(cfg::real<C>("view.lod_bias", at(&C::view, &ViewConfig::lod_bias), -16.0, 16.0, "added to every desired LOD, levels"))
        .add(cfg::boolean<C>("view.anisotropic", at(&C::view, &ViewConfig::anisotropic), "anisotropic LOD rule instead of max of lengths"))
        .add(cfg::real<C>("view.max_aniso", at(&C::view, &ViewConfig::max_aniso), 1.0, 64.0, "anisotropy clamp of the anisotropic rule"))
        .add(cfg::integer<C>("view.popin_divisor", at(&C::view, &ViewConfig::popin_divisor), 0, 256, "pop-in buffer divisor; 0 = the feedback buffer"))
        .add(cfg::integer<C>("view.feedback_every", at(&C::view, &ViewConfig::feedback_every), 1, 1000, "render feedback every k frames"))
        .add(cfg::integer<C>("view.feedback_latency", at(&C::view, &ViewConfig::feedback_latency), 0, 16,
                             "frames between rendering feedback and the runtime reading it (an engine's asynchronous "
                             "readback, PBO + fence: 2-3); pop-in is still measured on the current frame"))
        .add(cfg::integer<C>("view.render_threads", at(&C::view, &ViewConfig::render_threads), -1, 64,
                             "threads rendering feedback ahead of the frame loop, same results; 0 = the loop renders "
                             "(one core); -1 = auto (one per core up to 8; sim clock only)"))
        .add(cfg::real<C>("view.near_m", at(&C::view, &ViewConfig::near_m), 1e-6, 1e6, "near clip, m"))
        .add(cfg::real<C>("view.far_m", at(&C::view, &ViewConfig::far_m), 1e-3, 1e12, "far clip, m"))
        .add(cfg::text<C>("view.feedback_sampling", at(&C::view, &ViewConfig::feedback_sampling), one_of_mesh({"middle", "sequence"}),
                          "view.lod_model = gpu: the pixel of each divisor^2 feedback tile sampled: middle, or sequence (a "
                          "per-frame sequence visiting every pixel, Unreal's SampleVirtualTextureFeedbackSequence)"))
        .add(cfg::text<C>("view.lod_model", at(&C::view, &ViewConfig::lod_model), one_of_mesh({"analytic", "gpu"}),
                          "analytic: footprint per full-resolution pixel; gpu: a GPU feedback pass's request (2x2-quad "
                          "differences at feedback resolution, bias -log2(divisor); docs/gpu.md)"))
        .add(cfg::integer<C>("clipmap.clipsize", at(&C::clipmap, &ClipmapConfig::clipsize), 1, 1 << 20, "N: clip stack window side, texels (multiple of the tile)"))
        .add(cfg::real<C>("clipmap.update_threshold_tiles", at(&C::clipmap, &ClipmapConfig::update_threshold_tiles), 0.0, 64.0,
                          "hysteresis before a window recentres, tiles (Unity Clipmap UpdateThreshold)"))
        .add(cfg::integer<C>("clipmap.invalid_border_tiles", at(&C::clipmap, &ClipmapConfig::invalid_border_tiles), 0, 1 << 10,
                             "window edge tiles excluded from sampling (Yao 2007 §4-6)"))
        .add(cfg::integer<C>("clipmap.filter_margin_texels", at(&C::clipmap, &ClipmapConfig::filter_margin_texels), 0, 64,
                             "footprint half-width that must be valid (bilinear: 1)"))
        .add(cfg::integer<C>("terrain.sectors_x", at(&C::terrain, &TerrainConfig::sectors_x), 1, 4096, "terrain: sectors along x (VT Terrain Design: 16 × 512 m = 8192 m)"))
        .add(cfg::integer<C>("terrain.sectors_y", at(&C::terrain, &TerrainConfig::sectors_y), 1, 4096, "terrain: sectors along y"))
        .add(cfg::real<C>("terrain.sector_m", at(&C::terrain, &TerrainConfig::sector_m), 1e-3, 1e7, "terrain: sector side, m"))
        .add(cfg::integer<C>("terrain.brushes_per_sector", at(&C::terrain, &TerrainConfig::brushes_per_sector), 0, 1 << 20,
                             "terrain: brushes a sector blends (1-16: four RGBA masks, a 4×4 atlas)"))
        .add(cfg::integer<C>("terrain.brush_size", at(&C::terrain, &TerrainConfig::brush_size), 1, 1 << 16, "terrain: brush mip 0 side, texels (a power of two)"))
        .add(cfg::real<C>("terrain.brush_period_m", at(&C::terrain, &TerrainConfig::brush_period_m), 1e-6, 1e6, "terrain: ground one brush tile covers, m"))
        .add(cfg::integer<C>("terrain.brush_tree_levels", at(&C::terrain, &TerrainConfig::brush_tree_levels), 1, 17,
                             "terrain: brush quadtree levels (leaves mip 0, each level up one mip coarser)"))
        .add(cfg::real<C>("terrain.brush_compression", at(&C::terrain, &TerrainConfig::brush_compression), 1e-3, 1e3,
                          "terrain: decoded / disk bytes of a brush mip (1 = raw)"))
        .add(cfg::text<C>("terrain.brush_files", at(&C::terrain, &TerrainConfig::brush_files), nullptr,
                          "terrain, real clock: brush images, one per brush (files or patterns such as 'b/*.png', comma-separated); "
                          "empty = value noise"))
        .add(cfg::integer<C>("terrain.mask_size", at(&C::terrain, &TerrainConfig::mask_size), 1, 1 << 16, "terrain: mask texels a side per sector (divides the sector's texels)"))
        .add(cfg::integer<C>("terrain.decals_static", at(&C::terrain, &TerrainConfig::decals_static), 0, 1 << 24, "terrain: seeded static decals over the terrain"))
        .add(cfg::real<C>("terrain.decal_size_m", at(&C::terrain, &TerrainConfig::decal_size_m), 0.0, 1e6, "terrain: static decal side, m"))
        .add(cfg::integer<C>("terrain.decal_seed", at(&C::terrain, &TerrainConfig::decal_seed), 0, std::numeric_limits<std::int64_t>::max(),
                             "terrain: seed of the static decals' positions"))
        .add(cfg::real<C>("terrain.footprint_every_m", at(&C::terrain, &TerrainConfig::footprint_every_m), 0.0, 1e6,
                          "terrain: a footprint decal per this much camera travel, m; 0 = none"))
        .add(cfg::real<C>("terrain.footprint_size_m", at(&C::terrain, &TerrainConfig::footprint_size_m), 0.0, 1e6, "terrain: footprint side, m"))
        .add(cfg::integer<C>("terrain.footprint_levels", at(&C::terrain, &TerrainConfig::footprint_levels), 0, 63,
                             "terrain: finest levels a footprint re-renders (resident tiles there are produced again)"))
        .add(cfg::integer<C>("vt.pool_pages", at(&C::vt, &VtConfig::pool_pages), 1, std::int64_t{1} << 24,
                             "physical page pool, slots of one page in every layer (the VRAM budget)"))
        .add(cfg::integer<C>("vt.locked_levels", at(&C::vt, &VtConfig::locked_levels), 0, 63,
                             "coarsest levels locked resident: the fallback every sample has"))
        .add(cfg::integer<C>("vt.prefetch_finer_levels", at(&C::vt, &VtConfig::prefetch_finer_levels), 0, 2,
                             "also fetch pages 1 or 2 levels finer than desired into RAM (Unreal); 0 = off"))
        .add(cfg::integer<C>("vt.residency_window_frames", at(&C::vt, &VtConfig::residency_window_frames), 1, 100000,
                             "a page used within this many frames counts as visible (pool occupancy)"))
        .add(cfg::choice<C>("vt.pool_policy", at(&C::vt, &VtConfig::pool_policy), replacement_policies(),
                            "which unlocked page leaves the pool for an incoming one (pages used this frame never do)"))
        .add(cfg::real<C>("ram.capacity_MiB", at(&C::ram, &RamConfig::capacity_MiB), 0.0, 1e9, "RAM cache of decoded tiles, MiB (hard cap)"))
        .add(cfg::choice<C>("ram.policy", at(&C::ram, &RamConfig::policy), replacement_policies(),
                            "which decoded tile leaves the RAM cache when room is needed"))
        .add(cfg::real<C>("prefetch.lookahead_s", at(&C::prefetch, &PrefetchConfig::lookahead_s), 0.0, 3600.0,
                          "look-ahead along the motion (Yao 2007 §4-2), s; 0 = off"))
        .add(cfg::choice<C>("disk.preset", at(&C::disk, &DiskConfig::preset), disk_presets(), "disk model preset"))
        .add(cfg::real<C>("disk.latency_us", at(&C::disk, &DiskConfig::latency_us), -1.0, 1e9, "per-request latency, us; -1 = preset"))
        .add(cfg::real<C>("disk.bandwidth_MBps", at(&C::disk, &DiskConfig::bandwidth_MBps), -1.0, 1e9,
                          "transfer bandwidth, MB/s; 0 = unlimited; -1 = preset"))
        .add(cfg::integer<C>("disk.channels", at(&C::disk, &DiskConfig::channels), -1, 1 << 16, "requests in service at once; 0 = unlimited; -1 = preset"))
        .add(cfg::integer<C>("disk.queue_depth", at(&C::disk, &DiskConfig::queue_depth), -1, 1024,
                             "requests in service per channel (io_uring: io.queue_depth); -1 or 0 = preset (1)"))
        .add(cfg::real<C>("decode.throughput_MBps", at(&C::decode, &DecodeModel::throughput_MBps), 0.0, kInf, "decoded MB/s per worker; 0 = free"))
        .add(cfg::real<C>("decode.per_tile_us", at(&C::decode, &DecodeModel::per_tile_us), 0.0, 1e9, "fixed decode cost per tile, us"))
        .add(cfg::integer<C>("decode.workers", at(&C::decode, &DecodeModel::workers), 0, 1024, "decode workers; 0 = unlimited"))
        .add(cfg::integer<C>("upload.tiles_per_frame", at(&C::upload, &UploadModel::tiles_per_frame), -1, 1 << 20,
                             "upload budget, tiles per frame; -1 = no tile limit (0 is rejected)"))
        .add(cfg::integer<C>("upload.bytes_per_frame", at(&C::upload, &UploadModel::bytes_per_frame), -1, std::int64_t{1} << 40,
                             "upload budget, bytes per frame; -1 = no byte limit (0 is rejected)"))
        .add(cfg::real<C>("upload.link_MBps", at(&C::upload, &UploadModel::link_MBps), 0.0, kInf, "host to VRAM link, MB/s; 0 = unlimited"))
        .add(cfg::real<C>("upload.per_tile_us", at(&C::upload, &UploadModel::per_tile_us), 0.0, 1e6,
                          "fixed cost of each tile's copy (map, submit, driver), us; > 0: the link's budget is a frame of copy time"))
        .add(cfg::integer<C>("io.max_in_flight", at(&C::io, &IoConfig::max_in_flight), 1, 1 << 20, "jobs submitted to the IO/decode executor at once"))
        .add(cfg::integer<C>("io.max_retries", at(&C::io, &IoConfig::max_retries), 0, 100, "retries of a faulted tile before it fails"))
        .add(cfg::integer<C>("io.retry_backoff_frames", at(&C::io, &IoConfig::retry_backoff_frames), 0, 100000, "frames before a retry"))
        .add(cfg::integer<C>("io.threads", at(&C::io, &IoConfig::threads), 1, 256,
                             "real clock: IO pool threads (Yao 2007 §4-3); reads in flight at once: this, x io.queue_depth with io_uring"))
        .add(cfg::boolean<C>("io.direct", at(&C::io, &IoConfig::direct), "real clock: unbuffered O_DIRECT reads (Yao 2007 §4-3); false = page cache"))
        .add(cfg::choice<C>("io.engine", at(&C::io, &IoConfig::engine), io_engines(),
                            "real clock: how an IO thread reads (no io_uring in the kernel: psync, with a warning)"))
        .add(cfg::integer<C>("io.queue_depth", at(&C::io, &IoConfig::queue_depth), 1, 1024,
                             "real clock, io.engine = io_uring: reads in flight per IO thread"))
        .add(cfg::real<C>("io.fault_rate", at(&C::io, &IoConfig::faults, &FaultConfig::io_error_rate), 0.0, 1.0,
                          "probability that a read fails with EIO (injected, both clocks)"))
        .add(cfg::integer<C>("io.fault_seed", at(&C::io, &IoConfig::faults, &FaultConfig::seed), 0, std::numeric_limits<std::int64_t>::max(),
                             "seed of the injected fault pattern (per tile and attempt)"))
        .add(cfg::real<C>("io.fault.short_read_rate", at(&C::io, &IoConfig::faults, &FaultConfig::short_read_rate), 0.0, 1.0,
                          "probability that a read returns half its record (injected short read)"))
        .add(cfg::real<C>("io.fault.checksum_rate", at(&C::io, &IoConfig::faults, &FaultConfig::checksum_rate), 0.0, 1.0,
                          "probability that a read's payload arrives corrupted (caught by the checksum)"))
        .add(cfg::real<C>("io.fault.slow_rate", at(&C::io, &IoConfig::faults, &FaultConfig::slow_rate), 0.0, 1.0,
                          "probability that a read is slow (io.fault.slow_ms more)"))
        .add(cfg::real<C>("io.fault.slow_ms", at(&C::io, &IoConfig::faults, &FaultConfig::slow_ms), 0.0, 60000.0, "extra time of a slow read, ms"))
        .add(cfg::real<C>("produce.per_tile_us", at(&C::produce, &ProduceModel::per_tile_us), 0.0, 1e9,
                          "produced tile: fixed cost per tile (setup, mask fetch), us"))
        .add(cfg::real<C>("produce.per_texel_ns", at(&C::produce, &ProduceModel::per_texel_ns), 0.0, 1e6,
                          "produced tile: cost per output texel whatever its layers (store, pack), ns"))
        .add(cfg::real<C>("produce.per_layer_texel_ns", at(&C::produce, &ProduceModel::per_layer_texel_ns), 0.0, 1e6,
                          "produced tile: cost per output texel per blended brush layer (VT Terrain Design), ns"))
        .add(cfg::real<C>("produce.per_decal_us", at(&C::produce, &ProduceModel::per_decal_us), 0.0, 1e9,
                          "produced tile: cost per decal rendered over it, us"))
        .add(cfg::real<C>("produce.per_decal_texel_ns", at(&C::produce, &ProduceModel::per_decal_texel_ns), 0.0, 1e9,
                          "produced tile: cost per output texel a decal touches (one alpha blend), ns"))
        .add(cfg::integer<C>("produce.workers", at(&C::produce, &ProduceModel::workers), 0, 1024,
                             "production servers (real clock: the decode workers); 0 = unlimited"))
        .add(cfg::integer<C>("produce.tiles_per_frame", at(&C::produce, &ProduceModel::tiles_per_frame), 0, 1 << 20,
                             "production budget, produced tiles started per frame; 0 = unlimited (r.VT.MaxTilesProducedPerFrame)"))
        .add(cfg::choice<C>("throttle.policy", at(&C::throttle, &ThrottleParams::policy), throttle_policies(),
                            "MaxTextureLOD / residency policy"))
        .add(cfg::real<C>("throttle.deadline_ms", at(&C::throttle, &ThrottleParams::deadline_ms), 0.001, 1e7, "clamp levels whose backlog takes longer, ms"))
        .add(cfg::real<C>("throttle.relax_factor", at(&C::throttle, &ThrottleParams::relax_factor), 0.0, 1.0, "relax when the finer backlog fits deadline × this"))
        .add(cfg::integer<C>("throttle.relax_frames", at(&C::throttle, &ThrottleParams::relax_frames), 1, 100000, "... for this many consecutive frames"))
        .add(cfg::real<C>("throttle.drain_horizon_s", at(&C::throttle, &ThrottleParams::drain_horizon_s), 0.0, 1e6,
                          "an over-deadline backlog not back under it within this long clamps, s"))
        .add(cfg::real<C>("throttle.high_water", at(&C::throttle, &ThrottleParams::high_water), 0.0, 100.0,
                          "VT: pool pressure (RAGE) / visible residency (Unreal) above which the bias rises"))
        .add(cfg::real<C>("throttle.low_water", at(&C::throttle, &ThrottleParams::low_water), 0.0, 100.0, "VT: ... below which the bias falls"))
        .add(cfg::real<C>("throttle.bias_step", at(&C::throttle, &ThrottleParams::bias_step), 0.0, 16.0, "RAGE: feedback bias change per adjustment, levels"))
        .add(cfg::real<C>("throttle.max_bias", at(&C::throttle, &ThrottleParams::max_bias), 0.0, 16.0, "VT: largest feedback bias, levels"))
        .add(cfg::real<C>("throttle.adjust_rate", at(&C::throttle, &ThrottleParams::adjust_rate), 0.0, 100.0,
                          "Unreal: bias change per frame per unit of residency beyond a bound"))
        .add(cfg::real<C>("metrics.cut_m", at(&C::metrics, &MetricsConfig::cut_m), 0.0, 1e12, "a frame-to-frame jump longer than this is a cut, m"))
        .add(cfg::real<C>("metrics.turn_deg_per_s", at(&C::metrics, &MetricsConfig::turn_deg_per_s), 0.0, 1e6, "faster rotation is a fast turn, deg/s"))
        .add(cfg::real<C>("metrics.sharp_margin", at(&C::metrics, &MetricsConfig::sharp_margin), 0.0, 1.0,
                          "sharp again when blurry fraction <= pre-event baseline + this"))
        .add(cfg::integer<C>("metrics.thrash_frames", at(&C::metrics, &MetricsConfig::thrash_frames), 1, 1 << 20, "evicted then needed within this many frames = thrash"))
        .add(cfg::boolean<C>("metrics.opt", at(&C::metrics, &MetricsConfig::opt), "record each cache level's accesses; the summary adds Belady's bound, the offline replays and the LRU miss-ratio curve (docs/cache.md)"))
        .add(cfg::real<C>("metrics.warmup_s", at(&C::metrics, &MetricsConfig::warmup_s), 0.0, 1e9,
                          "the first seconds left out of the steady-state figures (latency, pop-in, rates); the start-up fill is reported in startup.*, s"));
    return t;
  }();
  return table;
}

[[noreturn]] static void bad(const std::string& key, const std::string& what) {
  throw InputError("config", "field '" + key + "': " + what);
}

// Least resampling rate: a frame every 100 s (slower, a trace would replay its first frame only).
constexpr double kMinFps = 0.01;
// Least bandwidth or throughput the simulated clock accepts: below it one tile's transfer time
// leaves the 64-bit nanosecond clock's range (1 KB/s moves a 1 MB tile in 1,000 s).
constexpr double kMinRateMBps = 1e-3;

void validate(const ReplayConfig& c) {
  // 0 means the trace's own times; a rate that slow (a subnormal one) would replay frame 0 only.
  if (c.run.fps != 0.0 && c.run.fps < kMinFps)
    bad("run.fps", fmt::format("{:g} Hz is below {:g} Hz (0 replays the trace's own times)", c.run.fps, kMinFps));
  const SystemInfo* system = streaming_systems().find(c.run.system);
  if (!system) bad("run.system", streaming_systems().unknown(c.run.system));
  system->validate(c);
  if (c.view.feedback_sampling == "sequence" && c.view.lod_model != "gpu")
    bad("view.feedback_sampling", "sequence moves the GPU model's sample within each feedback tile: set view.lod_model = gpu too");
  if (c.upload.tiles_per_frame == 0)
    bad("upload.tiles_per_frame", "a zero budget uploads nothing; use -1 for no tile limit");
  if (c.upload.bytes_per_frame == 0)
    bad("upload.bytes_per_frame", "a zero budget uploads nothing; use -1 for no byte limit");
  std::uint64_t max_tile = 0;
  for (const auto& L : c.texture.layers.specs) max_tile = std::max(max_tile, tile_decoded_bytes(c, L));
  if (c.upload.bytes_per_frame > 0 && static_cast<std::uint64_t>(c.upload.bytes_per_frame) < max_tile)
    bad("upload.bytes_per_frame", fmt::format("{} bytes is smaller than one tile ({} bytes): nothing could upload",
                                              c.upload.bytes_per_frame, max_tile));
  const double ram_bytes = c.ram.capacity_MiB * 1048576.0;
  if (ram_bytes < static_cast<double>(max_tile))
    bad("ram.capacity_MiB", fmt::format("{} MiB is smaller than one tile ({} bytes)", c.ram.capacity_MiB, max_tile));
  if (c.view.far_m <= c.view.near_m) bad("view.far_m", "must be greater than view.near_m");
  const auto rate = [](const char* key, double v) {
    if (v > 0.0 && v < kMinRateMBps)
      bad(key, fmt::format("{} MB/s is below {} MB/s (one tile would take longer than the clock can count)", v, kMinRateMBps));
  };
  rate("disk.bandwidth_MBps", c.disk.bandwidth_MBps);
  rate("decode.throughput_MBps", c.decode.throughput_MBps);
  rate("upload.link_MBps", c.upload.link_MBps);
  const SceneInfo* scene = scenes().find(c.scene.kind);
  if (!scene) bad("scene.kind", scenes().unknown(c.scene.kind));
  if (scene->file_required && c.scene.file.empty())
    bad("scene.file", fmt::format("scene.kind = \"{}\" needs {}", scene->name, scene->file));
  const std::int64_t max_side = std::max(c.texture.width, c.texture.height);
  if (max_side / c.texture.tile_size > TileKey::kMaxCoord)
    bad("texture.tile_size", "too many tiles a side for the 27-bit tile coordinates: use larger tiles");
}

std::string config_reference_markdown() {
  std::string md = replay_config_table().markdown(ReplayConfig{});
  const auto section = [&md](const std::string& title, const std::string& table) { md += "\n### " + title + "\n\n" + table; };
  section("`run.system`: streaming systems", streaming_systems().markdown("system"));
  section("`scene.kind`: scenes", scenes().markdown("scene"));
  section("`throttle.policy`: MaxTextureLOD and residency policies", throttle_policies().markdown("policy"));
  section("`ram.policy`, `vt.pool_policy`: replacement policies", replacement_policies().markdown("policy"));
  section("`disk.preset`: disk presets", disk_presets().markdown("preset"));
  section("`io.engine`: IO engines (real clock)", io_engines().markdown("engine"));
  section("`vtsim store build --codec`: tile codecs", codecs().markdown("codec"));
  return md;
}

}  // namespace vtsim

namespace vtsim {

ReplayConfig load_replay_config(const std::string& config_path, const std::vector<std::string>& sets,
                                const std::string& system) {
  return load_replay_config(config_path.empty() ? std::vector<std::string>{} : std::vector<std::string>{config_path}, sets, system);
}

ReplayConfig load_replay_config(const std::vector<std::string>& config_paths, const std::vector<std::string>& sets,
                                const std::string& system) {
  ReplayConfig cfg;
  const auto& table = replay_config_table();
  for (const std::string& p : config_paths)
    if (!p.empty()) load_toml_file(table, cfg, p);
  if (!system.empty()) table.set(cfg, "run.system", ConfigValue{system}, "--system");
  for (const auto& s : sets) apply_set(table, cfg, s);
  validate(cfg);
  return cfg;
}

}  // namespace vtsim
