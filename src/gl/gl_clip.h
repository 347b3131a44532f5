#pragma once
// The GL client's clip stack (docs/gpu.md, "The clipmap: a clip stack on the GPU"): the engine side
// of the streaming runtime (stream/runtime/streaming_runtime.h) for the clipmap system
// (stream/system/clipmap_system.h, cache/clipmap.h; Tanner, Migdal & Jones 1998).
//   - texels: a GL_TEXTURE_2D_ARRAY with one N×N layer per level (N = clipmap.clipsize; less when
//     the texture is smaller): the stack's windows and the pyramid's whole levels alike (a pyramid
//     level is at most N texels a side). Tile (x, y) of level l lives at toroidal slot (x mod w, y mod h) of layer l (w×h: the
//     level's window in tiles), so texel (u, v) of level l at (u mod wT, v mod hT).
//   - upload (IUploadSink): the tile's payload (its T×T texels inside the store's border) copied by
//     glTextureSubImage3D from the PBO ring (StreamPass) into its slot; every layer's upload is
//     mirrored on the CPU as cache/clipmap.h's slots do (a slot holds one tile and the layers of it
//     resident; a tile of another key overwrites it).
//   - apply: the frame's window updates; then per level the window (x0, y0, w, h tiles), its valid
//     texel rectangle (the window minus clipmap.invalid_border_tiles along edges that can move,
//     within the level: Clipmap::set_window's rule) as uniforms, and per slot whether it holds its
//     window tile in every layer (an SSBO of one uint per slot).
//   - draw: per pixel, the desired level d from its derivatives (the feedback's rule, floor of the
//     LOD); the level sampled is Clipmap::resident_level's: the finest l >= max(d, MaxTextureLOD
//     clamp) whose footprint (every texel within clipmap.filter_margin_texels of (u >> l, v >> l),
//     clamped at the level's edges) lies in the valid rectangle and in slots holding their tiles;
//     none: `levels` (grey). Texels filtered bilinearly with texelFetch at toroidal addresses. The
//     pop-in count is StreamPass's.
// Layer 0 of the texture (the albedo) is the one drawn; every layer's upload counts toward a
// slot's residency, as in the simulator.
#include <cstdint>
#include <memory>
#include <vector>

#include "gl/gl_stream.h"
#include "stream/system/i_system.h"

namespace vtsim::gl {

struct ClipGeometry {
  TextureExtent extent{1, 1};  // level-0 texels
  int tile = 128;              // T, payload texels a side
  int border = 0;              // texels of border each side in the store's tiles
  int channels = 4;            // 8-bit channels of layer 0
  int layers = 1;              // texture layers streamed per tile
  int clipsize = 1024;         // N
  int filter_margin = 1;       // clipmap.filter_margin_texels
  int invalid_border = 0;      // clipmap.invalid_border_tiles
};

class StreamedClip final : public StreamedTexture {
 public:
  // Throws InputError when the geometry cannot be drawn (clipsize not a multiple of the tile, a
  // texture side above 2^30 texels, more than 32 levels, or a clip stack above this GL's limits
  // or 1 GiB).
  StreamedClip(Renderer& r, const ClipGeometry& g);
  ~StreamedClip() override;
  StreamedClip(const StreamedClip&) = delete;
  StreamedClip& operator=(const StreamedClip&) = delete;

  void upload(const TileUpload& u) override;
  void apply(const FrameUpdates& u) override;
  // `sample_bias` is not applied: the clipmap system samples at max(desired, clamp) (its
  // apply_throttle reads the clamp only).
  PopinCount draw(const Camera& cam, const FeedbackSettings& fs, int clamp, double sample_bias = 0.0) override;
  std::vector<std::uint8_t> read_colour(int& w, int& h) override;
  std::uint64_t uploads() const override { return uploads_; }
  std::uint64_t copies() const override { return copies_; }
  double upload_gpu_ms() const override;
  std::uint64_t timed_frames() const override;

  int levels() const { return static_cast<int>(lv_.size()); }
  // Each level's window as the shader reads it (its uniforms read back from GL), finest first.
  std::vector<ClipWindow> gpu_windows() const;
  // Whether the GPU's slot of tile (tx, ty) of `level` holds that tile in every layer (the SSBO
  // read back from GL); false for a tile outside the level's window.
  bool gpu_tile_valid(int level, std::int64_t tx, std::int64_t ty) const;

 private:
  struct Slot {
    std::int64_t tx = -1, ty = -1;  // tile held (level coordinates), -1 = none
    std::uint32_t mask = 0;         // its resident layers
  };
  struct Level {
    std::int64_t texels_x = 0, texels_y = 0, tiles_x = 0, tiles_y = 0;
    std::int64_t wx = 0, wy = 0;  // window size, tiles
    ClipWindow win;               // last window the runtime reported
    int slot_off = 0;             // first slot in the SSBO
    std::vector<Slot> slots;
  };
  struct Impl;
  std::unique_ptr<Impl> impl_;
  Renderer& r_;
  ClipGeometry g_;
  std::vector<Level> lv_;
  std::uint32_t full_mask_ = 1;
  int layer_w_ = 0, layer_h_ = 0;  // the array's layers: the largest window, texels
  std::uint64_t uploads_ = 0, copies_ = 0;
  bool dirty_ = true;
};

}  // namespace vtsim::gl
