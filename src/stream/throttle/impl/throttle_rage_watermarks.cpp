// RAGE / id Tech 5's global feedback LOD bias with high and low water marks (van Waveren, "id Tech
// 5 Challenges", SIGGRAPH 2009 Beyond Programmable Shading: when the pages a view needs do not fit
// the physical page texture, globally raise the feedback LOD bias until the working set fits;
// Yao 2011 §5). The signal is the pool pressure: pages the view wants under the current bias
// (desired pages, their ancestors, the locked levels) over the pool's slots.
//   pressure > high_water: bias += bias_step (each frame, up to max_bias)
//   pressure < low_water for relax_frames consecutive frames: bias −= bias_step (down to 0)
// The bias changes what the feedback requests, not what the screen samples: finer pages still
// resident keep being sampled until the LRU evicts them (RAGE's page table falls back, it has no
// sampling bias).
#include <fmt/format.h>

#include <algorithm>

#include "stream/throttle/i_throttle.h"

namespace vtsim {

namespace {
class RageWatermarkThrottle final : public IThrottlePolicy {
 public:
  explicit RageWatermarkThrottle(const ThrottleParams& p) : p_(p) {}
  const char* name() const override { return "rage_watermarks"; }
  bool may_bias() const override { return true; }

  ThrottleDecision update(const ThrottleInput& in) override {
    const double pr = in.pool_pressure;
    ThrottleDecision d;
    if (pr > p_.high_water && bias_ < p_.max_bias) {
      bias_ = std::min(p_.max_bias, bias_ + p_.bias_step);
      calm_ = 0;
      d.reason = fmt::format("pressure {:.3f} > high water {:.2f}: bias {:.2f}", pr, p_.high_water, bias_);
    } else if (pr < p_.low_water && bias_ > 0.0) {
      if (++calm_ >= p_.relax_frames) {
        bias_ = std::max(0.0, bias_ - p_.bias_step);
        calm_ = 0;
        d.reason = fmt::format("pressure {:.3f} < low water {:.2f} for {} frames: bias {:.2f}", pr, p_.low_water,
                               p_.relax_frames, bias_);
      }
    } else {
      calm_ = 0;
    }
    d.bias = bias_;
    return d;
  }

 private:
  ThrottleParams p_;
  double bias_ = 0.0;
  int calm_ = 0;
};
}  // namespace

std::unique_ptr<IThrottlePolicy> make_throttle_rage_watermarks(const ThrottleParams& p) {
  return std::make_unique<RageWatermarkThrottle>(p);
}

}  // namespace vtsim
