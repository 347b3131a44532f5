#pragma once
// The CPU compositor of procedural virtual texturing (VT Terrain Design's produced tiles): one output tile
// of a clipmap level, T x T RGBA8 plus a border, blended from up to 16 brush layers of an Atlas
// (atlas.h) through per-texel weights from RGBA8 masks (4 layers a mask, bilinear).
// docs/produced.md, "The compositor".
//
// Sampling follows crazii 2017: the level comes from the *unwrapped* uv derivative (footprint =
// m_per_texel / period_m * S texels, lod = log2, rounded, clamped to the levels the border covers);
// then frac() wraps into the cell, the half-texel inset keeps the taps inside it, bilinear with 8
// bits of sub-texel position (D3D's required subtexel precision). Weights are normalised per texel
// to kWeightOne (2^14: the largest power of two whose 1.0 fits int16, so a weight times a byte
// summed over 16 layers fits 32 bits with room); out = (sum w c + 2^13) >> 14, round half up.
//
// Complexity: O(texels x active layers). Thread-safety: a Compositor holds scratch rows; use one
// per thread. No allocation per texel, no virtual call in the inner loops.
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "stream/exec/produce.h"
#include "stream/produce/atlas.h"

namespace vtsim::produce {

inline constexpr int kMaxLayers = 16;         // 4 RGBA8 masks of 4 weights
inline constexpr int kWeightBits = 14;        // see the file comment
inline constexpr int kWeightOne = 1 << kWeightBits;

struct BrushLayer {
  int cell = 0;          // brush index in the atlas
  double period_m = 1;   // metres one repeat of the brush covers
};

// Weights of layers 4i..4i+3 in the channels of mask i, over a world rectangle.
struct WeightMask {
  int width = 0, height = 0;               // texels
  const std::uint8_t* rgba = nullptr;      // width * height * 4
  double origin_x_m = 0, origin_y_m = 0;   // world position of texel (0, 0)'s corner, m
  double m_per_texel = 1;                  // m
};

// A decal (VT Terrain Design: footprints, damage) rendered over the blended brushes: a world rectangle of
// one colour, drawn with its exact area coverage of each output texel (anti-aliased edges, and a
// coarser level's texel is the mean of the finer ones it covers). A decal narrower than one output
// texel on either side is neither rendered nor counted at that level (TerrainSystem counts alike).
struct Decal {
  double x0_m = 0, y0_m = 0, x1_m = 0, y1_m = 0;  // world rectangle, m
  std::array<std::uint8_t, 4> rgba = {48, 40, 32, 192};  // colour; alpha = its opacity where it covers a texel whole
};

struct CompositeJob {
  const Atlas* atlas = nullptr;
  std::span<const BrushLayer> layers;   // <= kMaxLayers
  std::span<const WeightMask> masks;    // mask i weights layers 4i..4i+3
  std::span<const Decal> decals;
  double origin_x_m = 0, origin_y_m = 0;  // world position of payload texel (0, 0)'s corner, m
  double m_per_texel = 1;                 // m
  int tile = 128;                         // payload side T, texels
  int border = 0;                         // texels around the payload
};

// The level of `atlas` a layer samples for texels of m_per_texel: round(log2(m_per_texel /
// period_m * S)) clamped to [0, atlas.max_level()].
int select_level(const Atlas& atlas, double m_per_texel, double period_m);
// lod of a uv derivative (brush repeats per output texel) for a brush of side s: log2(|du| s).
double lod_from_derivative(double du_per_texel, int side);

// Whether decal d is drawn into texels of m_per_texel over the rectangle [x0, x1) x [y0, y1), m:
// it overlaps it and is at least a texel wide on both sides.
bool decal_drawn(const Decal& d, double m_per_texel, double x0, double y0, double x1, double y1);
// The texels decal d touches in an nx × ny output whose texel (0, 0) starts at (x0, y0) m: columns
// [i0, i1), rows [j0, j1) (empty outside). What draw_decals blends, and what the cost model counts
// (ProduceWork::decal_texels).
struct DecalSpan {
  int i0 = 0, i1 = 0, j0 = 0, j1 = 0;
  std::uint64_t texels() const {
    return i1 > i0 && j1 > j0 ? static_cast<std::uint64_t>(i1 - i0) * static_cast<std::uint64_t>(j1 - j0) : 0;
  }
};
DecalSpan decal_span(const Decal& d, double m_per_texel, double x0, double y0, int nx, int ny);
// Draws the job's decals over `out` (the (T + 2B)^2 blended texels), in order: per texel and decal,
// a = round(coverage x alpha), c = (c (255 - a) + decal a + 127) / 255. Every compose path, the
// reference and compose_exact end with it, so decals never break their byte equality.
void draw_decals(const CompositeJob& job, std::uint8_t* out);

// The layers a job blends (bit i = layer i): those whose mask channel is non-zero somewhere under
// the tile's bilinear footprint; layer 0 when none is.
std::uint32_t active_layers(const CompositeJob& job);
// What the job costs (exec/produce.h): texels with border, active layers, the decals it draws; the
// compositor samples exactly these layers and draws exactly these decals.
ProduceWork count_work(const CompositeJob& job);

// out[t] = (sum_l weights[l][t] * layers[l][4t+c] + 2^13) >> 14 for `texels` RGBA8 texels; the
// weights of a texel must sum to kWeightOne.
void blend_rgba8(const std::uint8_t* const* layers, const std::uint16_t* const* weights, int n_layers, std::size_t texels,
                 std::uint8_t* out);

// Bilinear sample of brush b at level m at uv (brush repeats, unwrapped), RGBA out. inset: the
// half-texel inset (crazii 2017 item 6); without it a tap at the cell edge reads the neighbouring cell.
void sample_bilinear(const Atlas& atlas, int m, int b, double u, double v, bool inset, std::uint8_t out[4]);

// The same tile in double precision with no fixed point: mask weights bilinear (clamped) and
// normalised exactly, every layer sampled bilinearly at its exact wrapped position, one rounding
// (half up). A reference for tests and bench_compositor: Compositor::compose stays within 1 of it
// per channel while neighbouring brush texels differ by < ~32 (docs/produced.md, "The compositor
// against OpenImageIO"). O(texels x layers), slow; no validation (run compose first).
void compose_exact(const CompositeJob& job, std::uint8_t* out);

// The instruction sets compose runs with: kGeneric is baseline x86-64 (SSE2), kAvx2 the same row
// kernels compiled for AVX2 (no FMA); kAuto the widest available. Every path gives the same bits
// (tests/test_compositor.cpp composes with each and compares the bytes).
enum class ComposePath { kAuto, kGeneric, kAvx2 };
// Whether this CPU (and build: the TSan build keeps the generic path only) runs `path`.
bool compose_path_available(ComposePath path);

// The per-texel loop compose ran before its row kernels (docs/produced.md, "The compositor"):
// compose gives exactly its bytes on every path. For tests and bench_compositor; ~4x slower.
void compose_reference(const CompositeJob& job, std::uint8_t* out);

class Compositor {
 public:
  // Writes (T + 2B)^2 RGBA8 texels to out. Throws InputError on a job it cannot run. `path` forces
  // an instruction set (tests, benches); an unavailable one is the caller's error.
  void compose(const CompositeJob& job, std::uint8_t* out, ComposePath path = ComposePath::kAuto);

 private:
  std::vector<float> raw_, inv_;      // kMaxLayers rows of raw weights; per texel kWeightOne / their sum
  std::vector<std::uint16_t> w_;      // kMaxLayers rows of normalised weights
  std::vector<std::uint16_t> best_, total_;  // per texel: heaviest weight, sum of the rounded weights
  std::vector<std::uint8_t> heavy_;   // per texel: the heaviest layer
  std::vector<std::int32_t> acc_;     // one row's blend sums, 4 a texel
  std::vector<int> mx_;               // per mask and output column: byte offsets of mask texels x0, x1
  std::vector<float> mfx_;            // ... and the fraction between them
  std::vector<float> hrow_;           // per mask, 2 cached mask rows interpolated at the columns, 4 x n
  std::vector<int> cache_y_;          // ... the mask rows they hold (-1: none)
  std::vector<int> tx_;               // per layer and output column: the brush tap column i0
  std::vector<std::uint32_t> twf_;    // ... and (f << 16) | (256 - f), f its 8-bit fraction
  std::vector<int> runs_;             // per layer, runs [a, b] of the brush columns the taps read
  std::vector<std::uint8_t> need_;    // scratch: columns a layer's taps read
  std::vector<std::uint16_t> vrow_;   // one layer's vertical pass (brush columns x 4, minus 2^15)
};

}  // namespace vtsim::produce
