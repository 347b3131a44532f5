#pragma once
// Procedural tile stores of any size (docs/store-format.md §6): deterministic terrain-like layers
// from gradient noise, generated tile by tile in bounded memory, so tests and benchmarks need
// no downloads.
//
// Every texel, at every level, is a pure function of (seed, layer kind, level, texel position):
// a height field h = fBm of 2D gradient (Perlin) noise over level-0 texel coordinates. Level l is
// the same function band-limited to its texel spacing 2^l (octaves shorter than 2 texels of that
// level are dropped, those between 2 and 4 texels faded in) and sampled at the centre of each
// texel's level-0 footprint: mips from the noise at the coarser scale, not by filtering, so levels
// are consistent without ever holding a level in memory. Borders and partial-tile padding use the
// same clamp-to-edge addressing as the image builder, and a border texel is computed from the
// noise, so it equals its neighbour tile's texel bit for bit.
#include <cstdint>
#include <string>
#include <vector>

#include "stream/store/store_builder.h"

namespace vtsim {

enum class GenKind {
  albedo,  // RGB, sRGB: water, sand, grass, rock, snow by height and slope, with detail noise
  normal,  // RGB, linear: tangent-space normal of the height field, (n * 0.5 + 0.5) * 255
  height,  // 1 channel, linear: the height field mapped to [0, 255]
};

struct GenLayer {
  std::string name;  // also the kind: "albedo", "normal" or "height" (optionally "albedo2"...)
  GenKind kind = GenKind::albedo;
  CodecSpec codec;
};

struct GenOptions {
  std::uint64_t width = 0, height = 0;  // level 0, texels
  std::uint32_t tile = 128, border = 4, levels = 0;
  std::vector<GenLayer> layers;
  std::uint64_t seed = 1;
  double feature_texels = 4096;  // wavelength of the coarsest noise octave, level-0 texels
  unsigned threads = 0;          // 0 = hardware threads; the file does not depend on it
};

// "albedo:zstd,normal:lz4:3,height:raw" -> layers. Throws InputError naming `where`.
std::vector<GenLayer> parse_gen_layers(const std::string& text, const std::string& where);

// Generates the store into out_path (crash-safe, as StoreWriter). Same options and seed ->
// identical file bytes. Memory: index + a window of tiles per worker.
BuildResult generate_store(const GenOptions& options, const std::string& out_path,
                           const ProgressFn& progress = {});

// The texels of one stored tile (with borders), as generate_store writes them; for tests.
std::vector<std::uint8_t> generate_tile(const GenOptions& options, std::uint32_t layer, std::uint32_t level,
                                        std::uint64_t tx, std::uint64_t ty);

}  // namespace vtsim
