#pragma once
// The GL client's streamed virtual texture (docs/gpu.md, "Streaming through the runtime"): the
// engine side of the streaming runtime (stream/runtime/streaming_runtime.h) for the VT system.
//   - upload (IUploadSink): the runtime's decoded page bytes copied into a physical page texture
//     (every pool slot a page with its borders, as the store holds them) by glTextureSubImage2D
//     from a ring of pixel-unpack buffers, each reused only after its fence; each frame's copies
//     timed with a GL_TIME_ELAPSED query read back when available.
//   - apply: the frame's page-table updates into a CPU mirror {page -> slot}, then the page-table
//     buffer (SSBO, one uint per page of every level: slot | resident level << 24) rebuilt from the
//     coarsest level down, each page falling back to its finest resident ancestor (RAGE / id Tech 5).
//   - draw: the main pass sampling the virtual texture at the level its derivatives want (never
//     finer than the MaxTextureLOD clamp), writing colour and, per pixel, (desired level + 1,
//     sampled level + 1) into an RG32UI target; a compute pass sums, on the GPU, the samples, the
//     blurry ones (sampled − desired ≥ 1) and the level deficit, read back once per frame.
// Layer 0 (the albedo) is the one drawn; the other layers' pages are counted as uploads but not
// copied (one physical texture).
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <vector>

#include "core/camera.h"
#include "core/tile_key.h"
#include "gl/gl_renderer.h"
#include "stream/runtime/streaming_runtime.h"

namespace vtsim::gl {

struct PopinCount {
  std::uint64_t samples = 0;  // pixels with a textured front-facing sample
  std::uint64_t blurry = 0;   // of those, sampled level − desired level ≥ 1
  std::uint64_t deficit = 0;  // sum of max(0, sampled − desired)
};

// The GL pixel format and sized internal format of 8-bit texels with `channels` channels (1..4).
unsigned gl_pixel_format(int channels);
unsigned gl_internal_format(int channels);

// What the streamed textures share (the VT's physical page texture, the clipmap's clip stack):
// the upload ring (16 pixel-unpack buffers, each reused only after its fence; each frame's copies
// bracketed by a GL_TIME_ELAPSED query read back when available) and the main pass's targets
// (colour, the RG32UI (desired + 1, sampled + 1) target, depth) with the compute pass that sums
// the pop-in on the GPU.
class StreamPass {
 public:
  // `staging_bytes`: the largest copy (one tile as the store holds it).
  explicit StreamPass(std::size_t staging_bytes);
  ~StreamPass();
  StreamPass(const StreamPass&) = delete;
  StreamPass& operator=(const StreamPass&) = delete;

  // Stages `n` bytes in the ring's next buffer, binds it as GL_PIXEL_UNPACK_BUFFER and calls
  // `copy` (the client's glTexture*SubImage* with a null offset), then fences the buffer.
  void copy(const void* bytes, std::size_t n, const std::function<void()>& copy);
  // The frame's copies are done: closes the frame's timer query, reads the ready ones.
  void end_uploads();
  // The main pass with `program` (bound textures and buffers are the caller's), then the count.
  PopinCount draw(Renderer& r, unsigned program, const Camera& cam, const FeedbackSettings& fs);
  std::vector<std::uint8_t> read_colour(int& w, int& h);
  double upload_gpu_ms() const { return upload_gpu_ms_; }
  std::uint64_t timed_frames() const { return timed_frames_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  double upload_gpu_ms_ = 0.0;
  std::uint64_t timed_frames_ = 0;
};

// A texture streamed through the runtime and drawn by the main pass: the runtime's sink, the
// frame's updates, the pass.
class StreamedTexture : public IUploadSink {
 public:
  // The frame's updates (after end_frame): page table or windows.
  virtual void apply(const FrameUpdates& u) = 0;
  // The main pass; returns the frame's pop-in counts (the GPU's sums). `clamp`: MaxTextureLOD;
  // `sample_bias`: the LOD bias the screen samples with (the desired level is measured without it).
  virtual PopinCount draw(const Camera& cam, const FeedbackSettings& fs, int clamp, double sample_bias = 0.0) = 0;
  // The last main pass as RGBA8, image rows top first.
  virtual std::vector<std::uint8_t> read_colour(int& w, int& h) = 0;
  virtual std::uint64_t uploads() const = 0;  // sink calls (every layer)
  virtual std::uint64_t copies() const = 0;   // layer-0 tiles copied to the GPU
  // GPU time of the uploads, summed over the frames whose queries were read back, ms.
  virtual double upload_gpu_ms() const = 0;
  virtual std::uint64_t timed_frames() const = 0;
};

class StreamedVt final : public StreamedTexture {
 public:
  // `tile`: payload texels a side; `border`: texels of border each side (the store's); `channels`:
  // 8-bit channels of layer 0's decoded texels (1..4); `slots`: the page pool; `levels`: the
  // system's levels (IStreamingSystem::num_levels: down to one page, not to one texel). Throws
  // InputError when the physical texture would exceed GL_MAX_TEXTURE_SIZE.
  StreamedVt(Renderer& r, int tile, int border, int channels, std::int64_t slots, int levels);
  ~StreamedVt() override;
  StreamedVt(const StreamedVt&) = delete;
  StreamedVt& operator=(const StreamedVt&) = delete;

  void upload(const TileUpload& u) override;
  // The frame's page-table updates (after end_frame).
  void apply(const FrameUpdates& u) override;
  PopinCount draw(const Camera& cam, const FeedbackSettings& fs, int clamp, double sample_bias = 0.0) override;
  std::vector<std::uint8_t> read_colour(int& w, int& h) override;

  std::uint64_t uploads() const override { return uploads_; }
  std::uint64_t copies() const override { return copies_; }
  const std::map<TileKey, std::int64_t>& page_table() const { return table_; }  // page -> slot
  // The page-table buffer as the GPU reads it (entry of page (level, x, y); kNone: nothing resident).
  static constexpr std::uint32_t kNone = 0xffffffffu;
  std::uint32_t entry(int level, std::int64_t x, std::int64_t y) const;
  double upload_gpu_ms() const override;
  std::uint64_t timed_frames() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  Renderer& r_;
  int channels_, levels_;
  std::int64_t slots_;
  std::uint64_t uploads_ = 0, copies_ = 0;
  std::map<TileKey, std::int64_t> table_;
  std::vector<std::uint32_t> pt_;
  std::vector<int> level_off_, tiles_x_, tiles_y_;
  bool pt_dirty_ = true;
};

}  // namespace vtsim::gl
