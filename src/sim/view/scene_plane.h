#pragma once
// The flat ground plane z = plane_z, textured by planar projection (docs/view.md): the reference
// scene, with a closed-form LOD the tests check against a long-double computation.
#include "sim/view/scene.h"

namespace vtsim {

// Planar ground texture: level-0 texel u = floor((x − x0)·tpm), v = floor((y − y0)·tpm).
struct GroundTexture {
  double x0_m = 0.0, y0_m = 0.0;  // world position of texel corner (0, 0), metres
  double texels_per_m = 128.0;    // level-0 texels per metre
  TextureExtent extent;           // level-0 texels
};

// O(buffer pixels) per frame, no allocation after the first frame per ViewBuffer; render is
// thread-safe (the scene is immutable).
class PlaneScene final : public IScene {
 public:
  PlaneScene(const GroundTexture& tex, double plane_z_m) : tex_(tex), z_(plane_z_m) {}
  void surface_at(const Camera& cam, const ViewParams& params, double px, double py, SurfaceHit& hit) const override;
  TextureExtent texture() const override { return tex_.extent; }
  void render(const Camera& cam, const ViewParams& params, ViewBuffer& out) const override;
  // Spans without materialising samples: per row, the batch arithmetic of render(), then a
  // branch-free test of whether each next sample stays in the open span (same class, level and
  // block as double comparisons); only a span's first sample takes the logarithm. O(pixels) with
  // a small constant, O(spans) scalar work. keep_samples falls back to render() + spans.
  void render_spans(const Camera& cam, const ViewParams& params, SpanBuffer& out) const override;
  void render_pixels(const SpanBuffer& sb, std::uint32_t pixel, std::uint32_t count,
                     std::vector<ViewSample>& out) const override;
  std::optional<double> ground_z(double, double) const override { return z_; }

 private:
  GroundTexture tex_;
  double z_;
};

}  // namespace vtsim
