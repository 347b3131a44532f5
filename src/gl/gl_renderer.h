#pragma once
// The GL reference client's renderer (docs/gpu.md): a scene's geometry (the same triangles and
// texel map the CPU view intersects: the plane as a grid of quads, the heightfield's cells split
// along their (i, j)–(i+1, j+1) diagonal, a mesh's or the town's triangles) drawn with
// camera-relative coordinates (double on the CPU, float relative to the camera on the GPU, and
// texel coordinates relative to an integer origin per chunk or triangle), a main colour pass and
// a feedback pass at 1/divisor into an RGBA32UI target read back asynchronously (PBO + fence,
// `latency` frames late).
#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/view.h"
#include "sim/view/gpu_model.h"
#include "sim/view/scene.h"

namespace vtsim::gl {

class Context;

// One feedback pixel as the GPU wrote it.
struct FeedbackTexel {
  std::uint32_t u = 0, v = 0;   // level-0 texel under the pixel (status 1)
  float lod = 0.0f;             // GL's rho rule with the bias (log2 texels per feedback pixel + bias)
  std::uint32_t status = 0;     // 0 nothing drawn, 1 sample, 2 back face, 3 outside the texture, 4 untextured
};

struct FeedbackFrame {
  long long frame = -1;         // the frame it was rendered in
  int width = 0, height = 0;    // feedback buffer, pixels (image rows: row 0 at the top)
  std::vector<FeedbackTexel> px;
};

// The feedback pass's knobs (the simulator's view.lod_model = gpu has the same ones).
struct FeedbackSettings {
  int divisor = 8;
  float lod_bias = 0.0f;        // the user's; the pass adds −log2(divisor)
  bool anisotropic = false;
  float max_aniso = 16.0f;
  double near_m = 0.05, far_m = 1.0e7;
  int latency = 2;              // frames between rendering feedback and reading it (k)
};

class Renderer {
 public:
  // Builds the geometry of cfg's scene (throws InputError like make_scene).
  Renderer(Context& ctx, const SceneConfig& cfg);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  TextureExtent texture() const { return extent_; }
  std::size_t triangles() const { return triangles_; }

  // Draws the main pass at the camera's full resolution (colour: desired level and tile checker).
  void draw_main(const Camera& cam, const FeedbackSettings& fs);
  // The last main pass as RGBA8, image rows top first.
  std::vector<std::uint8_t> read_main(int& w, int& h);

  // Image correctness (docs/gpu.md): the main pass textured with a procedural RGBA8 image over
  // the scene's texture extent (at most 4096² texels), sampled bilinearly at the level nearest
  // the GPU's LOD (floor(lod + 0.5)), never finer than `min_level`: `virtual_texture` false, from
  // a plain mipmapped texture; true, through a virtual texture in the RAGE / id Tech 5 style (a
  // page table of (physical slot, resident level) per tile of every level, falling back to the
  // finest resident ancestor, and a physical page cache of 64-texel tiles with 4-texel borders),
  // fully resident but for level `missing_level` (−1: none), whose pages fall back a level.
  void draw_textured(const Camera& cam, const FeedbackSettings& fs, bool virtual_texture, int min_level, int missing_level);

  // Renders the feedback pass of `frame` (sample pixel (ox, oy) of each divisor² tile) and
  // queues its readback; returns the frame now `latency` frames old when it is ready.
  bool feedback(const Camera& cam, const FeedbackSettings& fs, int ox, int oy, long long frame, FeedbackFrame& out);
  // Waits for and returns the oldest feedback still queued; false when none is.
  bool drain(FeedbackFrame& out);
  // Renders a feedback pass and reads it back at once (tests, checks).
  FeedbackFrame feedback_now(const Camera& cam, const FeedbackSettings& fs, int ox, int oy);

  // A client's own pass (gl_stream.h): `fragment_body` after the shared LOD functions (inputs
  // v_t, flat v_to; uniforms u_bias, u_aniso, u_inv_aniso2, u_extent), linked with the scene's
  // vertex shader. draw_program draws the scene with it into the bound framebuffer at the
  // camera's resolution, depth test on (the caller clears), u_bias = fs.lod_bias.
  static unsigned link_program(const std::string& fragment_body);
  void draw_program(unsigned program, const Camera& cam, const FeedbackSettings& fs);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  TextureExtent extent_;
  std::size_t triangles_ = 0;
};


}  // namespace vtsim::gl
