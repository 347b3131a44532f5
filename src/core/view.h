#pragma once
// What one frame sees: the per-sample output of the software feedback renderer (docs/view.md).
// These are the types the streaming systems consume; scenes and the renderer produce them.
#include <cstdint>
#include <vector>

namespace vtsim {

// The virtual texture a scene is parameterised into, at level 0.
struct TextureExtent {
  std::int64_t width = 0;   // texels
  std::int64_t height = 0;  // texels
};

// Number of mip levels of a W×H texture down to 1×1 with ceil halving: 1 + ceil(log2(max(W, H))).
int mip_level_count(TextureExtent e);

// Knobs of the feedback renderer.
struct ViewParams {
  int divisor = 8;             // feedback buffer = ceil(image / divisor) per axis; the main speed/error knob
  float lod_bias = 0.0f;       // added to every desired LOD (negative sharpens)
  bool anisotropic = false;    // false: Heckbert max of lengths (Yao 2007 §2-2-3); true: anisotropic LOD
  float max_aniso = 16.0f;     // anisotropy clamp for the anisotropic rule
  double near_m = 0.05;        // samples nearer than this are clipped
  double far_m = 1.0e7;        // samples farther than this are clipped
  // The GPU model only (view.lod_model = gpu, sim/view/gpu_model.h): the pixel (x, y) of each
  // divisor² feedback tile this frame's feedback samples; −1: the middle one (divisor / 2).
  int sample_ox = -1, sample_oy = -1;
};

// One feedback sample that hit a textured surface.
struct ViewSample {
  std::int64_t u = 0, v = 0;   // level-0 texel under the sample centre, 0 <= u < W, 0 <= v < H
  float lod = 0.0f;            // desired LOD: log2 of the full-resolution pixel footprint in level-0
                               // texels, plus bias; < 0 when magnified (level 0 is then desired)
  std::uint32_t pixel = 0;     // feedback-buffer pixel index, y * width + x
};

// Why buffer pixels produced no sample (each counts once).
struct ViewCounters {
  std::uint64_t sky = 0;           // the ray hit nothing
  std::uint64_t clipped = 0;       // hit outside [near, far]
  std::uint64_t backfacing = 0;    // nearest hit faces away from the camera
  std::uint64_t outside_texture = 0;  // hit a surface point whose texel lies outside the texture
  std::uint64_t untextured = 0;    // nearest hit is a mesh face without texture coordinates
};

struct ViewBuffer {
  int width = 0, height = 0;       // feedback buffer size, pixels
  int divisor = 1;                 // image size / buffer size
  std::vector<ViewSample> samples; // pixel order; only pixels that hit the textured surface
  ViewCounters counters;
};

// Desired mip level of a sample: floor(lod) clamped to [0, num_levels - 1].
inline int desired_level(float lod, int num_levels) {
  if (!(lod > 0.0f)) return 0;  // also maps NaN to 0, defensively
  const int l = static_cast<int>(lod);
  return l < num_levels - 1 ? l : num_levels - 1;
}

}  // namespace vtsim
