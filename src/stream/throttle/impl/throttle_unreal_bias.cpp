// Unreal Engine's residency mip bias (UE 4.2x/5.x FVirtualTexturePhysicalSpace, pool option
// bEnableResidencyMipMapBias; docs/vt.md): every frame, the pool's visible residency r (pages used
// within the last frames, here vt.residency_window_frames — Unreal's page free threshold — over
// the pool's slots) moves a global mip bias proportionally:
//   r > upper:              bias += rate · (r − upper)
//   bias > 0 and r < lower: bias −= rate · (lower − r)
// clamped to [0, max_bias]. upper/lower are throttle.high_water/low_water (Unreal ships 0.95 for
// both), rate throttle.adjust_rate (Unreal: 0.2), max_bias throttle.max_bias (Unreal: 4). The bias
// applies to the feedback and to what the screen samples (Unreal adds it to every virtual texture
// sample), so finer pages stop being used at once and age out of the pool.
// Residency cannot exceed 1, so the bias rises at most rate · (1 − upper) per frame (0.01 levels
// at Unreal's defaults: about 100 frames per level) — a slow, smooth response.
#include <fmt/format.h>

#include <algorithm>

#include "stream/throttle/i_throttle.h"

namespace vtsim {

namespace {
class UnrealBiasThrottle final : public IThrottlePolicy {
 public:
  explicit UnrealBiasThrottle(const ThrottleParams& p) : p_(p) {}
  const char* name() const override { return "unreal_bias"; }
  bool may_bias() const override { return true; }

  ThrottleDecision update(const ThrottleInput& in) override {
    const double r = in.pool_occupancy;
    const double before = bias_;
    if (bias_ > 0.0 && r < p_.low_water) bias_ -= p_.adjust_rate * (p_.low_water - r);
    else if (r > p_.high_water) bias_ += p_.adjust_rate * (r - p_.high_water);
    bias_ = std::clamp(bias_, 0.0, p_.max_bias);
    ThrottleDecision d;
    d.bias = bias_;
    d.sample_bias = bias_;
    if (bias_ != before)
      d.reason = fmt::format("residency {:.3f} {} {:.2f}: bias {:.3f}", r, bias_ > before ? ">" : "<",
                             bias_ > before ? p_.high_water : p_.low_water, bias_);
    return d;
  }

 private:
  ThrottleParams p_;
  double bias_ = 0.0;
};
}  // namespace

std::unique_ptr<IThrottlePolicy> make_throttle_unreal_bias(const ThrottleParams& p) {
  return std::make_unique<UnrealBiasThrottle>(p);
}

}  // namespace vtsim
