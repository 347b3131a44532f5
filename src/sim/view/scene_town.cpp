#include "sim/view/scene_town.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include <glm/geometric.hpp>

#include "core/error.h"
#include "core/tile_key.h"
#include "sim/view/scene_mesh.h"

namespace vtsim {

namespace {

constexpr std::int64_t kGapTexels = 4;   // between packed faces: one compressed block (crazii 2017)
constexpr double kMinHeightM = 6.0;      // two storeys
constexpr double kWallHeightM = 3.0;     // garden wall: hides the street behind it at eye level
constexpr double kWallThickM = 0.4;
constexpr double kLotGapM = 4.0;         // between the four buildings of a block

struct Rng {
  std::uint64_t s;
  double uniform(double lo, double hi) {  // [lo, hi)
    s += 0x9e3779b97f4a7c15ULL;
    return lo + (hi - lo) * static_cast<double>(mix64(s) >> 11) * 0x1p-53;
  }
};

struct Builder {
  Mesh mesh;
  double tpm;
  double W, H;                   // texture extent, texels
  std::int64_t tw, th;
  std::int64_t cur_x = 0, cur_y = 0, shelf_h = 0;  // shelf packer cursor, texels
  double x0, y0;

  // Quad c0 c1 c2 c3 (counter-clockwise seen from the front); c0→c1 spans the face's width,
  // c0→c3 its height. Texels: a packed rectangle at tpm texels per metre.
  void packed_quad(glm::dvec3 c0, glm::dvec3 c1, glm::dvec3 c2, glm::dvec3 c3) {
    const double w = glm::length(c1 - c0) * tpm, h = glm::length(c3 - c0) * tpm;
    const std::int64_t wi = static_cast<std::int64_t>(std::ceil(w)), hi = static_cast<std::int64_t>(std::ceil(h));
    if (cur_x + wi > tw) {
      cur_x = 0;
      cur_y += shelf_h + kGapTexels;
      shelf_h = 0;
    }
    if (wi > tw || cur_y + hi > th)
      throw InputError("texture.texels_per_m",
                       fmt::format("{:g} texels/m packs the town's faces into more than the {}x{}-texel texture: lower "
                                   "texture.texels_per_m or use a larger texture (texture.width and texture.height, or a "
                                   "store made with a larger `vtsim store gen --size`); texture.texels_per_m=4 fits a "
                                   "16384x16384 texture",
                                   tpm, tw, th));
    const double u0 = static_cast<double>(cur_x), v0 = static_cast<double>(cur_y);
    cur_x += wi + kGapTexels;
    shelf_h = std::max(shelf_h, hi);
    add_quad(c0, c1, c2, c3, {u0 / W, v0 / H}, {(u0 + w) / W, v0 / H}, {(u0 + w) / W, (v0 + h) / H},
             {u0 / W, (v0 + h) / H});
  }

  void add_quad(glm::dvec3 c0, glm::dvec3 c1, glm::dvec3 c2, glm::dvec3 c3, glm::dvec2 t0, glm::dvec2 t1,
                glm::dvec2 t2, glm::dvec2 t3) {
    const auto p = static_cast<std::uint32_t>(mesh.positions.size());
    const auto t = static_cast<std::int32_t>(mesh.uvs.size());
    for (const auto& c : {c0, c1, c2, c3}) mesh.positions.push_back(c);
    for (const auto& c : {t0, t1, t2, t3}) mesh.uvs.push_back(c);
    mesh.tris.push_back(Mesh::Tri{{p, p + 1, p + 2}, {t, t + 1, t + 2}});
    mesh.tris.push_back(Mesh::Tri{{p, p + 2, p + 3}, {t, t + 2, t + 3}});
  }

  // Four sides and a roof (no floor: it is never seen from outside; the ground closes the box).
  void box(double xa, double ya, double xb, double yb, double h) {
    const double za = 0.0, zb = h;
    mesh.solids.push_back(Mesh::Box{{xa, ya, za}, {xb, yb, zb}});
    packed_quad({xb, ya, za}, {xb, yb, za}, {xb, yb, zb}, {xb, ya, zb});  // +x
    packed_quad({xa, yb, za}, {xa, ya, za}, {xa, ya, zb}, {xa, yb, zb});  // −x
    packed_quad({xb, yb, za}, {xa, yb, za}, {xa, yb, zb}, {xb, yb, zb});  // +y
    packed_quad({xa, ya, za}, {xb, ya, za}, {xb, ya, zb}, {xa, ya, zb});  // −y
    packed_quad({xa, ya, zb}, {xb, ya, zb}, {xb, yb, zb}, {xa, yb, zb});  // roof
  }

  void ground_quad(double xa, double ya, double xb, double yb) {
    const auto uv = [&](double x, double y) { return glm::dvec2((x - x0) * tpm / W, (y - y0) * tpm / H); };
    add_quad({xa, ya, 0.0}, {xb, ya, 0.0}, {xb, yb, 0.0}, {xa, yb, 0.0}, uv(xa, ya), uv(xb, ya), uv(xb, yb),
             uv(xa, yb));
  }
};

void check_range(double v, double lo, double hi, const char* field) {
  if (!(v >= lo && v <= hi))
    throw InputError(field, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
}

}  // namespace

double town_size_m(const SceneConfig& cfg) {
  return cfg.town_blocks * (cfg.town_block_m + cfg.town_street_m) + cfg.town_street_m;
}

Mesh generate_town(const SceneConfig& cfg) {
  const TextureExtent ext = scene_texture(cfg);
  check_range(cfg.town_blocks, 1, 256, "town_blocks");
  check_range(cfg.town_block_m, 2.0 * kLotGapM + 2.0, 1000.0, "town_block_m");
  check_range(cfg.town_street_m, 2.0, 200.0, "town_street_m");
  check_range(cfg.town_max_height_m, kMinHeightM, 1000.0, "town_max_height_m");
  check_range(cfg.town_walls_per_block, 0, 64, "town_walls_per_block");
  const double S = town_size_m(cfg);
  if (S * cfg.texels_per_m > static_cast<double>(ext.width) || S * cfg.texels_per_m > static_cast<double>(ext.height))
  {
    // The town's layout is fixed (SceneConfig's defaults), so the density is the key to change.
    const double most = std::floor(static_cast<double>(std::min(ext.width, ext.height)) / S * 100.0) / 100.0;
    throw InputError("texture.texels_per_m",
                     fmt::format("{:g} texels/m puts the town's {:g} m ground on {:.0f} texels a side, more than the {}x{}-texel "
                                 "texture: lower texture.texels_per_m below {:g} (the ground alone; the faces need room too) or use a "
                                 "larger texture (texture.width and texture.height, or a larger `vtsim store gen --size`); "
                                 "texture.texels_per_m=4 fits a 16384x16384 texture",
                                 cfg.texels_per_m, S, S * cfg.texels_per_m, ext.width, ext.height, most));
  }
  Builder b;
  b.tpm = cfg.texels_per_m;
  b.tw = ext.width;
  b.th = ext.height;
  b.W = static_cast<double>(ext.width);
  b.H = static_cast<double>(ext.height);
  b.x0 = cfg.origin_x_m;
  b.y0 = cfg.origin_y_m;
  b.cur_y = static_cast<std::int64_t>(std::ceil(S * b.tpm)) + kGapTexels;
  const double pitch = cfg.town_block_m + cfg.town_street_m;
  // Ground: one quad per block pitch, so that triangles stay small next to the camera.
  const int cells = cfg.town_blocks + 1;
  const double cell = S / cells;
  for (int j = 0; j < cells; ++j)
    for (int i = 0; i < cells; ++i)
      b.ground_quad(b.x0 + i * cell, b.y0 + j * cell, b.x0 + (i + 1) * cell, b.y0 + (j + 1) * cell);
  // Below the ground: a ray from above meets the ground's front side first, and a camera below
  // it sees the ground's back (docs/view.md, "Scenes", mesh).
  b.mesh.solids.push_back(Mesh::Box{{-INFINITY, -INFINITY, -INFINITY}, {INFINITY, INFINITY, 0.0}});
  Rng rng{cfg.seed};
  const double lot = (cfg.town_block_m - kLotGapM) / 2.0;
  for (int bj = 0; bj < cfg.town_blocks; ++bj)
    for (int bi = 0; bi < cfg.town_blocks; ++bi) {
      const double bx = b.x0 + cfg.town_street_m + bi * pitch, by = b.y0 + cfg.town_street_m + bj * pitch;
      for (int l = 0; l < 4; ++l) {
        const double lx = bx + (l & 1) * (lot + kLotGapM), ly = by + (l >> 1) * (lot + kLotGapM);
        const double inset = rng.uniform(0.0, 0.2 * lot);
        const double h = rng.uniform(kMinHeightM, cfg.town_max_height_m);
        b.box(lx + inset, ly + inset, lx + lot - inset, ly + lot - inset, h);
      }
      // Walls stand in the street, 2 m off the block, along a random side of it.
      for (int w = 0; w < cfg.town_walls_per_block; ++w) {
        const int side = static_cast<int>(rng.uniform(0.0, 4.0));
        const double len = rng.uniform(0.25, 1.0) * cfg.town_block_m;
        const double off = rng.uniform(0.0, cfg.town_block_m - len);
        const double gap = std::min(2.0, 0.25 * cfg.town_street_m);
        switch (side) {
          case 0: b.box(bx + off, by - gap - kWallThickM, bx + off + len, by - gap, kWallHeightM); break;
          case 1: b.box(bx + off, by + cfg.town_block_m + gap, bx + off + len, by + cfg.town_block_m + gap + kWallThickM, kWallHeightM); break;
          case 2: b.box(bx - gap - kWallThickM, by + off, bx - gap, by + off + len, kWallHeightM); break;
          default: b.box(bx + cfg.town_block_m + gap, by + off, bx + cfg.town_block_m + gap + kWallThickM, by + off + len, kWallHeightM); break;
        }
      }
    }
  return std::move(b.mesh);
}

// The table's "town" (scene.cpp).
std::unique_ptr<IScene> make_town_scene(const SceneConfig& cfg, TextureExtent extent) {
  return std::make_unique<MeshScene>(generate_town(cfg), extent);
}

// The table's "town": its layout is fixed (SceneConfig's defaults) from the texture's origin.
std::string town_where(double origin_x_m, double origin_y_m) {
  const double S = town_size_m(SceneConfig{});
  return fmt::format("the town covers x {:.1f}..{:.1f} m, y {:.1f}..{:.1f} m (a walk in it: `vtsim trace gen walk "
                     "--start 30,8`)",
                     origin_x_m, origin_x_m + S, origin_y_m, origin_y_m + S);
}

Mesh tile_town(const Mesh& town, double period_m, int tiles) {
  Mesh m;
  m.uvs = town.uvs;
  for (int j = 0; j < tiles; ++j)
    for (int i = 0; i < tiles; ++i) {
      const glm::dvec3 off(i * period_m, j * period_m, 0.0);
      const auto p0 = static_cast<std::uint32_t>(m.positions.size());
      for (const glm::dvec3& p : town.positions) m.positions.push_back(p + off);
      for (Mesh::Tri t : town.tris) {
        for (auto& v : t.p) v += p0;
        m.tris.push_back(t);
      }
      for (const Mesh::Box& b : town.solids)
        if (std::isfinite(b.lo.x) || (i == 0 && j == 0)) m.solids.push_back(Mesh::Box{b.lo + off, b.hi + off});
    }
  return m;
}

}  // namespace vtsim
