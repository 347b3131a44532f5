#pragma once
// The GPU's feedback model (docs/gpu.md, view.lod_model = gpu): what an engine's feedback pass at
// 1/divisor resolution requests, as opposed to the analytic footprint per full-resolution pixel
// (lod.h). Per feedback pixel: the ray through one pixel of its divisor² tile (the middle one,
// or one per frame from a sequence that visits them all), the texel coordinates of the surface it
// hits, and their screen-space derivatives as a GPU takes them: finite differences within the
// 2×2 quad of feedback pixels (GL's dFdxFine / dFdyFine: the horizontal partner in the same quad
// row, the vertical one in the same quad column), the partner's texel coordinates extrapolated on
// the same triangle's plane (a helper invocation interpolates the same triangle's attributes).
// ρ is GL's (4.5 core §8.14.1): isotropic max(|dT/dx|, |dT/dy|), or the anisotropic rule of lod.h;
// the LOD bias of a reduced pass, −log2(divisor), is added to the user's.
#include <cstdint>
#include <memory>

#include <glm/vec3.hpp>

#include "core/camera.h"
#include "core/view.h"

namespace vtsim {

class IScene;

// Which pixel of each feedback tile the feedback pass samples in a frame.
enum class FeedbackSampling {
  middle,    // the middle pixel, every frame (the analytic view's sample)
  sequence,  // a per-frame sequence visiting every pixel of the tile (Unreal's
             // SampleVirtualTextureFeedbackSequence)
};

// The surface a ray meets first (IScene::surface_at): where, its plane, and its affine texel map.
struct SurfaceHit {
  enum Kind : std::uint8_t { none, sample, backfacing, outside_texture, untextured, clipped };
  Kind kind = none;
  glm::dvec3 p{0.0};           // hit point, world metres
  glm::dvec3 n{0.0, 0.0, 1.0}; // the hit triangle's plane normal (any length)
  glm::dvec3 gu{0.0}, gv{0.0}; // texel gradients on the plane, level-0 texels per metre
  double tu = 0.0, tv = 0.0;   // continuous level-0 texel coordinates at p
};

// The pixel (ox, oy) of the divisor² tile sampled in `frame` (0 <= ox, oy < divisor). middle:
// divisor / 2 (camera.h sample_pixel of a whole tile). sequence: j = frame·s mod divisor², s the
// first integer from 0.618·divisor² coprime to divisor² (a full cycle: every pixel once per
// divisor² frames, consecutive frames far apart), ox = j mod divisor, oy = j / divisor.
void feedback_tile_offset(FeedbackSampling mode, long long frame, int divisor, int& ox, int& oy);

// The full-resolution pixel position of feedback pixel b's sample: b·divisor + o + 0.5 (beyond
// the image for the last, partial tile: the GPU's feedback viewport covers whole tiles).
inline double gpu_sample_pos(int b, int divisor, int o) { return static_cast<double>(b) * divisor + o + 0.5; }

// Renders one feedback frame of `scene` with the GPU model into `out` (ViewBuffer semantics:
// samples in pixel order, counters; lod = GL's ρ at feedback resolution in level-0 texels plus
// params.lod_bias − log2(divisor)). Throws InputError for invalid params, std::logic_error for a
// scene without surface_at.
void render_gpu_model(const IScene& scene, const Camera& cam, const ViewParams& params, int ox, int oy,
                      ViewBuffer& out);

// `inner` drawn with the GPU model (view.lod_model = gpu in a replay): render() is
// render_gpu_model at the pixel params.sample_ox / sample_oy of each tile (−1: the middle one;
// view.feedback_sampling = sequence sets them per frame, feedback_tile_offset), render_spans the spans of its samples
// (IScene's default); texture, surface_at and load_warnings are the inner scene's.
std::unique_ptr<IScene> make_gpu_model_scene(std::unique_ptr<IScene> inner);

}  // namespace vtsim
