#pragma once
// Texture atlases for procedural virtual texturing (crazii 2017): K square brushes of one
// power-of-two side S packed into a cols x rows grid, each cell bordered by N texels of the brush
// itself *wrapped*, built mip by mip: atlas level m holds each brush's own level m (box-filtered
// from its level m-1, never a downsample of the atlas across cells) with a border of that level
// wrapped (texel -1 = texel S_m - 1). docs/produced.md, "Atlases (crazii 2017)".
//
// Border and mips. As one GPU texture with a standard chain, level m of the atlas is the level-0
// layout halved m times, so the border is N_m = N / 2^m texels and the chain stays cell-aligned only
// while 2^m divides N. A bilinear tap at the cell edge needs one texel of border, so the border
// *covers* the levels with N_m >= 1 (levels 0..log2 N for N a power of two); sampling is clamped to
// those (Atlas::levels). constant_border instead keeps N texels at every level (each level its own
// texture or array slice, not a standard chain) and covers every level down to 1 x 1. N = 0 (no
// border) leaves the half-texel inset as the only guard: no bleeding, but no filtering across the
// wrap either (crazii 2017 item 6).
//
// Transition (crazii 2017 item 7): `transition` texels at each edge of level 0 cross-faded with the
// mirrored texels across the wrap, so a brush that does not tile shows no hard seam; 4 texels =
// one BC block. Applied before the mips, which inherit it.
//
// Thread-safety: build_atlas is a pure function; an Atlas is immutable after it.
#include <cstdint>
#include <string>
#include <vector>

namespace vtsim::produce {

// An RGBA8 image, row-major, 4 bytes a texel.
struct Rgba8 {
  int width = 0, height = 0;        // texels
  std::vector<std::uint8_t> texels;  // width * height * 4
};

struct AtlasParams {
  int cols = 4;                // cells per row
  int rows = 0;                // cell rows; 0 = ceil(brushes / cols)
  int border = 4;              // N, texels around each cell at level 0 (4 = one BC block, crazii 2017 item 7)
  int transition = 0;          // texels cross-faded at each brush edge (crazii 2017 item 7); 0 = none
  bool constant_border = false;  // N texels at every level (not a standard chain), covering all levels
  int max_side = 16384;        // largest atlas side, texels (D3D11/12 and Vulkan's common 2D limit)
};

// One level of the atlas.
struct AtlasLevel {
  int brush_side = 0;  // S_m, texels
  int border = 0;      // N_m, texels
  int cell = 0;        // S_m + 2 N_m, texels
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgba;  // width * height * 4
  // The texel (x, y) of brush `b`'s level, x, y in [-border, brush_side + border).
  std::size_t offset(int cols, int b, int x, int y) const {
    const int cx = (b % cols) * cell + border + x, cy = (b / cols) * cell + border + y;
    return (static_cast<std::size_t>(cy) * static_cast<std::size_t>(width) + static_cast<std::size_t>(cx)) * 4;
  }
  const std::uint8_t* texel(int cols, int b, int x, int y) const { return &rgba[offset(cols, b, x, y)]; }
};

struct Atlas {
  int cols = 0, rows = 0, brushes = 0;
  int side = 0;        // S, texels
  int border = 0;      // N, texels at level 0
  int transition = 0;  // texels
  bool constant_border = false;
  // Levels 0..levels.size()-1: the levels the border covers (N_m >= 1), or with border 0 every
  // level down to 1 x 1 (guarded by the half-texel inset only).
  std::vector<AtlasLevel> levels;
  int max_level() const { return static_cast<int>(levels.size()) - 1; }
};

// The box-filter chain of one brush: level 0 is `brush` itself, level m+1 the rounded mean of 2 x 2
// texels of level m, down to 1 x 1. Values averaged as stored (no sRGB decode: brushes are
// blended in the same space they are stored in).
std::vector<Rgba8> brush_mips(const Rgba8& brush);

// Cross-fades `t` texels at each edge with the texels mirrored across the wrap (crazii 2017 item 7).
void apply_transition(Rgba8& brush, int t);

// Builds the atlas. names[i] names brush i in errors (a file path); throws InputError naming the
// brush or the field (cols, rows, border, transition, max_side) for: a side that is not a power of
// two or not square, brushes of different sizes, more brushes than cells, an atlas side over
// max_side, a negative border, a transition over half the side.
Atlas build_atlas(const std::vector<Rgba8>& brushes, const std::vector<std::string>& names, const AtlasParams& params);

}  // namespace vtsim::produce
