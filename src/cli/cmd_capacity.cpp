// vtsim capacity: memory of a clipmap (stack + pyramid, per layer) against a full mip chain, and
// seed 000 §2-3's table recomputed (docs/clipmap.md).
#include <fmt/format.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "cache/clipmap.h"
#include "cli/commands.h"
#include "core/error.h"
#include "sim/replay_config.h"

namespace vtsim::cli {

namespace {

std::string human_bytes(double b) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB"};
  int u = 0;
  while (b >= 1024.0 && u < 5) b /= 1024.0, ++u;
  return fmt::format("{:.{}f} {}", b, u == 0 ? 0 : 2, units[u]);
}

struct CapacityArgs {
  std::int64_t width = 1 << 20, height = 0;
  int clipsize = 1024, tile = 128;
  std::string layers = "albedo:rgba8";
  bool json = false, seed_table = false;
  std::string system = "clipmap";
};

// Seed 000 §2-3's table: texture sides × clipsizes, in bytes at 2 bytes per texel (the unit that
// reproduces its "Full Mipmap" row: 682 KB for a 512² chain = 349,525 texels × 2 B).
void print_seed_table() {
  const std::int64_t sides[] = {512, 1024, 4096, 32768, 67108864};
  const char* seed[4][5] = {{"682KB", "2.7MB", "42.7MB", "2.7GB", "10923TB"},
                            {"682KB", "1.1MB", "2.2MB", "3.7MB", "9.1MB"},
                            {"682KB", "2.7MB", "6.7MB", "12.7MB", "34.7MB"},
                            {"682KB", "2.7MB", "18.7MB", "42.7MB", "131.7MB"}};
  const char* rows[] = {"Full Mipmap", "512 Clipmap", "1024 Clipmap", "2048 Clipmap"};
  const int clips[] = {0, 512, 1024, 2048};
  fmt::print("seed 000 §2-3 recomputed at 2 bytes/texel (binary units; the seed's figure in brackets)\n");
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

void run_capacity(const CapacityArgs& a) {
  if (a.system != "clipmap")
    throw InputError("--system", "'" + a.system + "': capacity is implemented for: clipmap");
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
  auto* c = app.add_subcommand("capacity", "VRAM needed by a clipmap (stack + pyramid per layer) vs a full mip chain");
  c->add_option("--system", a->system, "clipmap")->capture_default_str();
  c->add_option("--width,--size", a->width, "level-0 width, texels (any size)")->capture_default_str()->check(CLI::Range(std::int64_t{1}, std::int64_t{1} << 40));
  c->add_option("--height", a->height, "level-0 height, texels (default: = width)")->check(CLI::Range(std::int64_t{0}, std::int64_t{1} << 40));
  c->add_option("--clipsize", a->clipsize, "clip stack window side N, texels")->capture_default_str();
  c->add_option("--tile", a->tile, "tile size T, texels (N must be a multiple)")->capture_default_str();
  c->add_option("--layers", a->layers, "layers name:format[:ratio],... (rgba8, rgb8, rg8, r8, rgba16f, bc1..bc7)")->capture_default_str();
  c->add_flag("--json", a->json, "print JSON");
  c->add_flag("--seed-table", a->seed_table, "recompute seed 000 §2-3's memory table and show the seed's figures");
  c->callback([a] { run_capacity(*a); });
}

}  // namespace vtsim::cli
