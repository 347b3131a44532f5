// vtsim capacity: memory of a clipmap (stack + pyramid, per layer) against a full mip chain, and
// Yao 2007 §2-3's table recomputed (docs/clipmap.md); for --system vt, a virtual texture's disk
// size, page-table size and the physical pool a screen needs, and Yao 2011's arithmetic checked
// (docs/vt.md "Capacity"); for --system terrain, VT Terrain Design's produced clipmap from a config: stored
// texels against stored brushes and masks, the clipmap, and the brushes resident to render
// (docs/produced.md "Capacity").
#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "cache/clipmap.h"
#include "cache/page_table.h"
#include "cli/cli_io.h"
#include "cli/commands.h"
#include "cli/config_load.h"
#include "cli/format.h"
#include "core/error.h"
#include "sim/run/replay_config.h"
#include "sim/run/systems.h"

namespace vtsim::cli {

namespace {

struct CapacityArgs {
  std::int64_t width = 1 << 20, height = 0;
  int clipsize = 1024, tile = 128;
  std::string layers = "albedo:rgba8";
  bool json = false, seed_table = false;
  std::string system = RunConfig{}.system;  // the replay's default system
  // vt
  int border = 0;
  std::string screen = "1920x1080";
  double overdraw = 3.0, redundancy = 1.0, texels_per_pixel = 1.0;
  bool seed_check = false;
  // every system: a replay config's texture (width, height, tile_size, border, layers) and
  // clipmap.clipsize; a flag given on the command line wins; terrain reads its [terrain] too
  std::vector<std::string> configs;
  std::vector<std::string> sets;
  std::set<std::string> given;  // the flags the command line gave
  // terrain
  std::string camera;
};

std::string with_commas(std::uint64_t v) {
  std::string s = std::to_string(v), out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (i > 0 && (s.size() - i) % 3 == 0) out += ',';
    out += s[i];
  }
  return out;
}

std::string decimal_bytes(double b) {
  const char* units[] = {"B", "kB", "MB", "GB", "TB", "PB"};
  int u = 0;
  while (b >= 1000.0 && u < 5) b /= 1000.0, ++u;
  return fmt::format("{:.{}f} {}", b, u == 0 ? 0 : 2, units[u]);
}

// Yao 2011's figures, each recomputed (docs/vt.md "Yao 2011 arithmetic").
void print_seed001_checks() {
  fmt::print("Yao 2011 arithmetic, recomputed (MB = 10^6 B, MiB = 2^20 B)\n");
  const double s2a = 1680.0 * 1050.0 * 3.0;
  fmt::print("  §2  one screen of texels, 1680×1050 × 3 B         = {} B = {:.2f} MB = {:.2f} MiB   (Yao 2011: \"5MB\"; agrees)\n",
             with_commas(static_cast<std::uint64_t>(s2a)), s2a / 1e6, s2a / 1048576.0);
  const double s2b = 6.0 * 3.0 * 1680.0 * 1050.0 * 4.0;
  fmt::print("  §2  6 screens × 3 overdraw × 1680×1050 × 4 B      = {} B = {:.1f} MB = {:.1f} MiB   (Yao 2011: \"120MB\": "
             "121.1 MiB rounded down; 127.0 in decimal MB)\n",
             with_commas(static_cast<std::uint64_t>(s2b)), s2b / 1e6, s2b / 1048576.0);
  fmt::print("  §3.1 1680×1080 feedback pixels                    = {}   (Yao 2011: 1814400; agrees, though §2's screen was "
             "1680×1050 = {})\n",
             with_commas(1680ull * 1080ull), with_commas(1680ull * 1050ull));
  fmt::print("  §3.2 128K² texture, 128-texel pages               = {}×{} pages at level 0 = a {}² page table (Yao 2011: "
             "1024×1024; agrees)\n",
             131072 / 128, 131072 / 128, 131072 / 128);
  const std::uint64_t side = 4096ull * 512ull;
  const double texels = static_cast<double>(side) * static_cast<double>(side);
  fmt::print("  §5  4096² page table × 512-texel pages            = {} texels a side (Yao 2011: 2097152; agrees)\n",
             with_commas(side));
  fmt::print("  §5  {}² texels                             = 2^42 = {:.0f} Gi texels: the article's \"4096 G\" counts texels\n",
             with_commas(side), texels / 1073741824.0);
  fmt::print("      × 4 B/texel                                   = 2^44 B = {:.1f} TB = {:.0f} TiB (not 4096 GB = 4 TiB: the "
             "article dropped the 4 bytes)\n",
             texels * 4.0 / 1e12, texels * 4.0 / 1099511627776.0);
  fmt::print("      with its mip levels (× (1 − 4^-13)/(1 − 1/4) ≈ 4/3, down to one 512² page) = {:.1f} TiB\n",
             (texels * 4.0 * 4.0 / 3.0 - 4.0 * 512.0 * 512.0 / 3.0) / 1099511627776.0);
  const double pt = (4096.0 * 4096.0 * 4.0 - 1.0) / 3.0;
  fmt::print("      its dense mip-mapped page table: {} entries × 4 B = {:.1f} MB\n",
             with_commas(static_cast<std::uint64_t>(pt)), pt * 4.0 / 1e6);
}

void run_vt_capacity(const CapacityArgs& a) {
  if (a.seed_check) {
    print_seed001_checks();
    return;
  }
  const std::int64_t h = a.height > 0 ? a.height : a.width;
  std::vector<LayerSpec> layers;
  try {
    layers = parse_layers(a.layers);
  } catch (const std::invalid_argument& e) {
    throw InputError("--layers", e.what());
  }
  if (a.tile < 2 || a.tile % 2 != 0) throw InputError("--tile", fmt::format("{}: a VT page must be even", a.tile));
  if (a.border < 0) throw InputError("--border", fmt::format("{} texels: a border is 0 or more", a.border));
  if (a.border > a.tile)
    throw InputError("--border", fmt::format("{} texels is larger than the page ({} texels)", a.border, a.tile));
  int sw = 0, sh = 0;
  char x = 0;
  if (std::sscanf(a.screen.c_str(), "%d%c%d", &sw, &x, &sh) != 3 || (x != 'x' && x != 'X') || sw <= 0 || sh <= 0 ||
      sw > 65536 || sh > 65536)
    throw InputError("--screen", "'" + a.screen + "': expected WxH, e.g. 1920x1080");
  VtCapacityInput in;
  in.extent = {a.width, h};
  in.page_size = a.tile;
  in.border = a.border;
  in.bytes_per_texel = 0;
  in.disk_bytes_per_texel = 0;
  for (const auto& L : layers) {
    in.bytes_per_texel += L.bytes_per_texel;
    in.disk_bytes_per_texel += L.bytes_per_texel / L.compression_ratio;
  }
  in.screen_w = sw;
  in.screen_h = sh;
  in.overdraw = a.overdraw;
  in.redundancy = a.redundancy;
  in.texels_per_pixel = a.texels_per_pixel;
  // The pool's texel count is printed as an integer: keep it exact (a double holds 2^53).
  const double screen_texels = static_cast<double>(sw) * sh * a.overdraw * a.redundancy * a.texels_per_pixel;
  if (!(screen_texels <= 0x1p53))
    throw InputError("--overdraw", fmt::format("screen {}×{} × overdraw × redundancy × texels/pixel = {:.3g} texels, "
                                               "beyond 2^53 (9.0e15)", sw, sh, screen_texels));
  VtCapacity c;
  try {
    c = vt_capacity(in);
  } catch (const std::invalid_argument& e) {
    throw InputError("--width", e.what());
  }
  const int side = a.tile + 2 * a.border;
  nlohmann::json j;
  j["texture"] = {{"width", a.width}, {"height", h}};
  j["page_size"] = a.tile;
  j["border"] = a.border;
  j["stored_side"] = side;
  j["levels"] = c.levels;
  j["pages"] = c.pages;
  j["pages_level0"] = c.pages_level0;
  j["payload_texels"] = c.payload_texels;
  j["stored_texels"] = c.stored_texels;
  j["disk_bytes"] = c.disk_bytes;
  j["decoded_bytes"] = c.decoded_bytes;
  j["page_table"] = {{"entries", c.page_table_entries},
                     {"bytes", c.page_table_bytes},
                     {"entry_bytes", PageTable::kEntryBytes},
                     {"level0", {c.page_table_level0_side_x, c.page_table_level0_side_y}}};
  j["pool"] = {{"screen", {sw, sh}},
               {"overdraw", a.overdraw},
               {"redundancy", a.redundancy},
               {"texels_per_pixel", a.texels_per_pixel},
               {"screen_texels", c.screen_texels},
               {"pages", c.pool_pages},
               {"bytes", c.pool_bytes}};
  if (a.json) {
    fmt::print("{}\n", j.dump(2));
    return;
  }
  fmt::print("virtual texture {}×{}, pages of {}² texels + {}-texel border ({}² stored), {} levels down to one page\n",
             a.width, h, a.tile, a.border, side, c.levels);
  fmt::print("  pages          {} ({} at level 0)\n", with_commas(c.pages), with_commas(c.pages_level0));
  fmt::print("  texels         {} payload (all levels), {} stored (+{:.1f}% borders and partial edge pages)\n",
             with_commas(c.payload_texels), with_commas(c.stored_texels),
             100.0 * (static_cast<double>(c.stored_texels) / static_cast<double>(c.payload_texels) - 1.0));
  fmt::print("  disk           {} ({}), decoded {} ({})\n", decimal_bytes(c.disk_bytes), human_bytes(c.disk_bytes),
             decimal_bytes(c.decoded_bytes), human_bytes(c.decoded_bytes));
  fmt::print("  page table     dense mip-mapped: {} entries × {} B = {} ({}); level 0 alone {}×{}\n",
             with_commas(c.page_table_entries), PageTable::kEntryBytes, decimal_bytes(static_cast<double>(c.page_table_bytes)),
             human_bytes(static_cast<double>(c.page_table_bytes)), c.page_table_level0_side_x, c.page_table_level0_side_y);
  fmt::print("                 sparse (vtsim): only mapped pages, ~16-64 B each (hash slots at load <= 1/2)\n");
  fmt::print("  pool           {}×{} screen × overdraw {} × redundancy {} × {} texel/pixel = {} texels\n", sw, sh, a.overdraw,
             a.redundancy, a.texels_per_pixel, with_commas(static_cast<std::uint64_t>(c.screen_texels)));
  fmt::print("                 = {} pages of {}² payload = {} pages × {}² × {} B = {} ({})\n", with_commas(c.pool_pages),
             a.tile, with_commas(c.pool_pages), side, in.bytes_per_texel, decimal_bytes(c.pool_bytes), human_bytes(c.pool_bytes));
}

// Yao 2007 §2-3's table: texture sides × clipsizes, in bytes at 2 bytes per texel (the unit that
// reproduces its "Full Mipmap" row: 682 KB for a 512² chain = 349,525 texels × 2 B).
void print_seed_table() {
  const std::int64_t sides[] = {512, 1024, 4096, 32768, 67108864};
  const char* seed[4][5] = {{"682KB", "2.7MB", "42.7MB", "2.7GB", "10923TB"},
                            {"682KB", "1.1MB", "2.2MB", "3.7MB", "9.1MB"},
                            {"682KB", "2.7MB", "6.7MB", "12.7MB", "34.7MB"},
                            {"682KB", "2.7MB", "18.7MB", "42.7MB", "131.7MB"}};
  const char* rows[] = {"Full Mipmap", "512 Clipmap", "1024 Clipmap", "2048 Clipmap"};
  const int clips[] = {0, 512, 1024, 2048};
  fmt::print("Yao 2007 §2-3 recomputed at 2 bytes/texel (binary units; the article's figure in brackets)\n");
  fmt::print("{:<14}", "type / side");
  for (auto s : sides) fmt::print("{:>24}", s);
  fmt::print("\n");
  for (int r = 0; r < 4; ++r) {
    fmt::print("{:<14}", rows[r]);
    for (int c = 0; c < 5; ++c) {
      const ClipmapMemory m = clipmap_memory({sides[c], sides[c]}, 1, r == 0 ? static_cast<int>(sides[c]) : clips[r]);
      const double bytes = 2.0 * static_cast<double>(r == 0 ? m.full_mip_texels : m.stack_texels + m.pyramid_texels);
      fmt::print("{:>24}", fmt::format("{} [{}]", human_bytes(bytes), seed[r][c]));
    }
    fmt::print("\n");
  }
}


// Bytes of brush mip m of one brush as the terrain stores it: the quadtree's root (mip
// brush_tree_levels − 1) carries its tail down to 1×1 (TerrainSystem::tile_sizes).
std::uint64_t brush_mip_bytes_of(const TerrainConfig& t, int m) {
  const int last = m == t.brush_tree_levels - 1 ? std::countr_zero(static_cast<unsigned>(t.brush_size)) : m;
  std::uint64_t b = 0;
  for (int k = m; k <= last; ++k) {
    const auto side = static_cast<std::uint64_t>(std::max(1, t.brush_size >> k));
    b += 4 * side * side;
  }
  return b;
}

void run_terrain_capacity(const CapacityArgs& a) {
  const ReplayConfig cfg = load_cli_config(a.configs, a.sets, a.system);
  const TerrainConfig& t = cfg.terrain;
  const double world_x = t.sector_m * t.sectors_x, world_y = t.sector_m * t.sectors_y;
  // The camera in world metres (default: the terrain's centre, a sector corner with an even count).
  double cx = cfg.texture.origin_x_m + world_x / 2, cy = cfg.texture.origin_y_m + world_y / 2;
  if (!a.camera.empty()) {
    char comma = 0, extra = 0;
    if (std::sscanf(a.camera.c_str(), "%lf%c%lf%c", &cx, &comma, &cy, &extra) != 3 || comma != ',' || !std::isfinite(cx) ||
        !std::isfinite(cy))
      throw InputError("--camera", "'" + a.camera + "': expected X,Y in metres, e.g. 4096,4096");
  }
  const double rx = cx - cfg.texture.origin_x_m, ry = cy - cfg.texture.origin_y_m;
  if (rx < 0 || ry < 0 || rx > world_x || ry > world_y)
    throw InputError("--camera", fmt::format("({}, {}) m is outside the terrain [{}, {}] × [{}, {}] m", cx, cy, cfg.texture.origin_x_m,
                                             cfg.texture.origin_x_m + world_x, cfg.texture.origin_y_m, cfg.texture.origin_y_m + world_y));
  const int clipsize = cfg.clipmap.clipsize;
  const TerrainCapacity c = terrain_capacity(t, cfg.texture.texels_per_m, clipsize, rx, ry);
  const std::uint64_t brush_disk =
      static_cast<std::uint64_t>(static_cast<double>(c.brush_bytes_all_mips) / t.brush_compression);
  const std::uint64_t stored = brush_disk + c.mask_bytes;
  // Far Cry 4's world (Chen 2015): 10 km × 10 km at 10 texels/cm, 4 B a texel (VT Terrain Design's "363.8 T").
  constexpr double kFarCry4StoredTexelBytes = 1e7 * 1e7 * 4.0;
  const ClipmapMemory mem = clipmap_memory({c.texels_side_x, c.texels_side_y}, cfg.texture.tile_size, clipsize);
  nlohmann::json levels = nlohmann::json::array();
  for (std::size_t l = 0; l < c.level_mip.size(); ++l) {
    const int m = c.level_mip[l];
    const double window_m = static_cast<double>(clipsize) * std::exp2(static_cast<double>(l)) / cfg.texture.texels_per_m;
    levels.push_back({{"level", l},
                      {"window_m", window_m},
                      {"brush_mip", m},
                      {"sectors", c.level_sectors[l]},
                      {"brush_bytes", static_cast<std::uint64_t>(c.level_sectors[l]) * static_cast<std::uint64_t>(t.brushes_per_sector) *
                                          brush_mip_bytes_of(t, m)}});
  }
  nlohmann::json j;
  j["system"] = a.system;
  j[a.system] = {{"sectors", {t.sectors_x, t.sectors_y}},
                  {"sector_m", t.sector_m},
                  {"world_m", {world_x, world_y}},
                  {"texels_per_m", cfg.texture.texels_per_m},
                  {"texels", {c.texels_side_x, c.texels_side_y}},
                  {"brushes_per_sector", t.brushes_per_sector},
                  {"brush_size", t.brush_size},
                  {"brush_tree_levels", t.brush_tree_levels},
                  {"mask_size", t.mask_size}};
  j["stored_texel_bytes"] = c.stored_equiv_bytes;
  j["far_cry_4_stored_texel_bytes"] = kFarCry4StoredTexelBytes;
  j["brushes"] = c.brushes;
  j["brush_bytes_mip0"] = c.brush_bytes_mip0;
  j["brush_bytes_all_mips"] = c.brush_bytes_all_mips;
  j["brush_disk_bytes"] = brush_disk;
  j["masks"] = c.masks;
  j["mask_bytes"] = c.mask_bytes;
  j["stored_bytes"] = stored;
  j["stored_texels_per_stored_byte"] = c.stored_equiv_bytes / static_cast<double>(stored);
  j["clipmap"] = {{"clipsize", clipsize},
                  {"full_levels", c.full_levels},
                  {"full_levels_bytes", c.clipmap_full_levels_bytes},
                  {"stack_and_pyramid_bytes", static_cast<std::uint64_t>(mem.stack_texels + mem.pyramid_texels) * 4}};
  j["camera_m"] = {cx, cy};
  j["levels"] = levels;
  j["brush_resident_by_mip"] = c.brush_resident_by_mip;
  j["brush_resident_bytes"] = c.brush_resident_bytes;
  if (a.json) {
    fmt::print("{}\n", j.dump(2));
    return;
  }
  const auto mib = [](double b) { return fmt::format("{:.1f} MiB", b / 1048576.0); };
  fmt::print("terrain: {} × {} sectors of {} m = {} × {} m at {} texels/m ({} × {} texels), {} brushes a sector of {}² "
             "({} quadtree levels), masks of {}²\n",
             t.sectors_x, t.sectors_y, t.sector_m, world_x, world_y, cfg.texture.texels_per_m, c.texels_side_x, c.texels_side_y,
             t.brushes_per_sector, t.brush_size, t.brush_tree_levels, t.mask_size);
  fmt::print("  stored texels, 4 B     {} ({} B); Far Cry 4's 10 km at 10 texels/cm: {}\n", human_bytes(c.stored_equiv_bytes),
             with_commas(static_cast<std::uint64_t>(c.stored_equiv_bytes)), human_bytes(kFarCry4StoredTexelBytes));
  fmt::print("  brushes                {} × {}² × 4 B = {} at mip 0; every mip {} ({} B); on disk / {} = {}\n", c.brushes, t.brush_size,
             mib(static_cast<double>(c.brush_bytes_mip0)), mib(static_cast<double>(c.brush_bytes_all_mips)),
             with_commas(c.brush_bytes_all_mips), t.brush_compression, mib(static_cast<double>(brush_disk)));
  fmt::print("  masks                  {} ({} a sector) × {}² × 4 B = {}\n", c.masks, (t.brushes_per_sector + 3) / 4, t.mask_size,
             mib(static_cast<double>(c.mask_bytes)));
  fmt::print("  stored (brushes+masks) {} ({} B): 1/{:.0f} of the stored texels\n", mib(static_cast<double>(stored)), with_commas(stored),
             c.stored_equiv_bytes / static_cast<double>(stored));
  fmt::print("  clipmap                {} levels × {}² × 4 B = {} (stack + pyramid in {}-texel tiles: {})\n", c.full_levels, clipsize,
             mib(static_cast<double>(c.clipmap_full_levels_bytes)), cfg.texture.tile_size,
             mib(static_cast<double>(mem.stack_texels + mem.pyramid_texels) * 4.0));
  fmt::print("  brushes resident to render, camera at ({}, {}) m:\n", cx, cy);
  fmt::print("    {:>5} {:>10} {:>9} {:>8} {:>14}\n", "level", "window m", "brush mip", "sectors", "brush bytes");
  for (const auto& e : levels)
    fmt::print("    {:>5} {:>10} {:>9} {:>8} {:>14}\n", e["level"].get<int>(), e["window_m"].get<double>(), e["brush_mip"].get<int>(),
               e["sectors"].get<int>(), mib(static_cast<double>(e["brush_bytes"].get<std::uint64_t>())));
  std::string by_mip;
  for (std::size_t m = 0; m < c.brush_resident_by_mip.size(); ++m)
    by_mip += fmt::format("{}mip {} {}", m ? ", " : "", m, mib(static_cast<double>(c.brush_resident_by_mip[m])));
  fmt::print("    union over levels (each mip on its widest window's sectors): {}\n", by_mip);
  fmt::print("    = {} B = {}\n", with_commas(c.brush_resident_bytes), mib(static_cast<double>(c.brush_resident_bytes)));
}

// `a` with the config's values where the command line gave no flag (clipmap and vt).
CapacityArgs capacity_with_config(const CapacityArgs& a) {
  if (a.configs.empty() && a.sets.empty()) return a;
  const ReplayConfig cfg = load_cli_config(a.configs, a.sets, a.system);
  const auto given = [&](const char* flag) { return a.given.count(flag) > 0; };
  CapacityArgs b = a;
  if (!given("--width")) b.width = cfg.texture.width;
  if (!given("--height")) b.height = given("--width") ? 0 : cfg.texture.height;  // --width alone: square, as without -c
  if (!given("--tile")) b.tile = cfg.texture.tile_size;
  if (!given("--clipsize")) b.clipsize = cfg.clipmap.clipsize;
  if (!given("--layers")) b.layers = cfg.texture.layers.text;
  if (!given("--border")) b.border = cfg.texture.border;
  return b;
}

// The systems whose capacity report is `r`, as "a, b".
std::string systems_reporting(CapacityReport r) {
  std::string names;
  for (const SystemInfo& s : streaming_systems().entries())
    if (s.caps.capacity == r) names += (names.empty() ? "" : ", ") + std::string(s.name);
  return names;
}

void run_capacity(const CapacityArgs& args) {
  const SystemInfo* info = streaming_systems().find(args.system);
  const CapacityReport report = info ? info->caps.capacity : CapacityReport::window_stack;
  if (report != CapacityReport::produced && !args.camera.empty())
    throw InputError("--camera", "only with --system " + systems_reporting(CapacityReport::produced));
  if (!info) throw InputError("--system", "'" + args.system + "': one of " + streaming_systems().names(", "));
  const CapacityArgs a = report == CapacityReport::produced ? args : capacity_with_config(args);
  if (report == CapacityReport::page_pool) {
    run_vt_capacity(a);
    return;
  }
  if (report == CapacityReport::produced) {
    run_terrain_capacity(a);
    return;
  }
  if (a.seed_table) {
    print_seed_table();
    return;
  }
  const std::int64_t h = a.height > 0 ? a.height : a.width;
  if (a.tile <= 0 || a.clipsize <= 0 || a.clipsize % a.tile != 0)
    throw InputError("--clipsize", fmt::format("{} is not a positive multiple of --tile {}", a.clipsize, a.tile));
  std::vector<LayerSpec> layers;
  try {
    layers = parse_layers(a.layers);
  } catch (const std::invalid_argument& e) {
    throw InputError("--layers", e.what());
  }
  const ClipmapMemory m = clipmap_memory({a.width, h}, a.tile, a.clipsize);
  double bpt = 0;
  for (const auto& L : layers) bpt += L.bytes_per_texel;
  nlohmann::json j;
  j["texture"] = {{"width", a.width}, {"height", h}};
  j["clipsize"] = a.clipsize;
  j["tile_size"] = a.tile;
  j["levels"] = m.levels;
  j["stack_levels"] = m.stack_levels;
  j["pyramid_levels"] = m.pyramid_levels;
  j["stack_texels"] = m.stack_texels;
  j["pyramid_texels"] = m.pyramid_texels;
  j["full_mip_texels"] = m.full_mip_texels;
  nlohmann::json per_layer = nlohmann::json::array();
  for (const auto& L : layers) {
    per_layer.push_back({{"name", L.name},
                         {"format", L.format},
                         {"bytes_per_texel", L.bytes_per_texel},
                         {"stack_bytes", static_cast<double>(m.stack_texels) * L.bytes_per_texel},
                         {"pyramid_bytes", static_cast<double>(m.pyramid_texels) * L.bytes_per_texel},
                         {"full_mip_bytes", static_cast<double>(m.full_mip_texels) * L.bytes_per_texel}});
  }
  j["layers"] = per_layer;
  const double clip_bytes = static_cast<double>(m.stack_texels + m.pyramid_texels) * bpt;
  const double full_bytes = static_cast<double>(m.full_mip_texels) * bpt;
  j["clipmap_bytes"] = clip_bytes;
  j["full_mip_bytes"] = full_bytes;
  j["ratio_full_to_clipmap"] = full_bytes / clip_bytes;
  if (a.json) {
    fmt::print("{}\n", j.dump(2));
    return;
  }
  fmt::print("clipmap of a {}×{} texture, clipsize {}, tiles {}: {} levels = {} stack + {} pyramid\n", a.width, h,
             a.clipsize, a.tile, m.levels, m.stack_levels, m.pyramid_levels);
  for (const auto& L : layers)
    fmt::print("  {:<10} {:<7} stack {:>12}  pyramid {:>12}  total {:>12}   full mip chain {:>12}\n", L.name, L.format,
               human_bytes(static_cast<double>(m.stack_texels) * L.bytes_per_texel),
               human_bytes(static_cast<double>(m.pyramid_texels) * L.bytes_per_texel),
               human_bytes(static_cast<double>(m.stack_texels + m.pyramid_texels) * L.bytes_per_texel),
               human_bytes(static_cast<double>(m.full_mip_texels) * L.bytes_per_texel));
  fmt::print("  all layers: clipmap {} vs full mip chain {} ({:.1f}× smaller)\n", human_bytes(clip_bytes),
             human_bytes(full_bytes), full_bytes / clip_bytes);
}

}  // namespace

void register_capacity_commands(CLI::App& app) {
  auto a = std::make_shared<CapacityArgs>();
  auto* c = app.add_subcommand("capacity", "VRAM needed by a clipmap (stack + pyramid per layer) vs a full mip chain; "
                                           "for --system vt: disk, page table and the pool a screen needs; for --system terrain: "
                                           "VT Terrain Design's stored brushes and masks, clipmap and resident brushes");
  c->add_option("--system", a->system, streaming_systems().names(" | "))->capture_default_str();
  c->add_option("--width,--size", a->width, "level-0 width, texels (any size)")->capture_default_str()->check(CLI::Range(std::int64_t{1}, std::int64_t{1} << 40));
  c->add_option("--height", a->height, "level-0 height, texels (default: = width)")->check(CLI::Range(std::int64_t{0}, std::int64_t{1} << 40));
  c->add_option("--clipsize", a->clipsize, "clip stack window side N, texels")->capture_default_str();
  c->add_option("--tile", a->tile, "tile size T, texels (N must be a multiple)")->capture_default_str();
  c->add_option("--layers", a->layers, "layers name:format[:ratio],... (rgba8, rgb8, rg8, r8, rgba16f, bc1..bc7)")->capture_default_str();
  c->add_flag("--json", a->json, "print JSON");
  c->add_flag("--seed-table", a->seed_table, "recompute Yao 2007 §2-3's memory table and show the article's figures");
  c->add_option("--border", a->border, "vt: page border B, texels (stored P+2B)")->capture_default_str();
  c->add_option("--screen", a->screen, "vt: screen WxH, pixels")->capture_default_str();
  c->add_option("--overdraw", a->overdraw, "vt: surfaces drawn per pixel (Yao 2011 §2: 3)")->capture_default_str()->check(CLI::Range(1e-6, 1e6));
  c->add_option("--redundancy", a->redundancy, "vt: screen-sized textures of cache slack (Yao 2011 §2: 6)")->capture_default_str()->check(CLI::Range(1e-6, 1e6));
  c->add_option("--texels-per-pixel", a->texels_per_pixel, "vt: texels per pixel at the desired level (Yao 2011 §2: 1)")->capture_default_str()->check(CLI::Range(1e-6, 1e6));
  c->add_flag("--seed-check", a->seed_check, "vt: recompute Yao 2011's arithmetic (§2, §3, §5)");
  add_config_options(c, a->configs, a->sets,
                     "; capacity reads texture.* and clipmap.clipsize, a flag given wins (terrain: [terrain] too, e.g. "
                     "docs/examples/terrain.toml)");
  c->add_option("--camera", a->camera, "terrain: camera X,Y, m (default: the terrain's centre)");
  c->callback([a, c] {
    a->given = flags_given(c);
    run_capacity(*a);
  });
}

}  // namespace vtsim::cli
