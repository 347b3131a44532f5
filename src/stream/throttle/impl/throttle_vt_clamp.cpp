// MaxTextureLOD for a virtual texture's page pool (Yao 2007 §4-4, applied to Yao 2011 §5's "the
// pages a frame needs exceed the physical page texture"): clamp the finest level requested and
// sampled, in whole levels. Two reasons to clamp; the coarser clamp wins:
//  - the IO backlog: the deadline policy (throttle_deadline.cpp) as for the clipmap — the camera
//    outruns the updates;
//  - the pool: the pages wanted at levels >= c must fit in high_water × slots. The wanted set holds
//    every ancestor of every desired page, so clamping at c requests exactly the wanted pages of
//    levels >= c: pages(c) = sum_{l >= c} demand[l], no estimate needed.
// Engage at once to the finest level that fits (at most the coarsest clamp: the locked levels).
// Relax one level after relax_frames consecutive frames in which the next finer level would fit
// under low_water × slots (hysteresis: a level's worth of pages is ~4× the next coarser one's on
// surfaces facing the camera, so relaxing only while far below the high mark avoids ping-pong).
#include <fmt/format.h>

#include <algorithm>

#include "stream/throttle/i_throttle.h"

namespace vtsim {

std::unique_ptr<IThrottlePolicy> make_throttle_deadline(const ThrottleParams&);

namespace {
class VtClampThrottle final : public IThrottlePolicy {
 public:
  explicit VtClampThrottle(const ThrottleParams& p) : p_(p), io_(make_throttle_deadline(p)) {}
  const char* name() const override { return "vt_clamp"; }

  ThrottleDecision update(const ThrottleInput& in) override {
    ThrottleDecision d = io_->update(in);
    std::string reason;
    const auto& demand = in.pool_demand_by_level;
    if (in.pool_slots > 0 && !demand.empty()) {
      const int n = static_cast<int>(demand.size());
      suffix_.assign(static_cast<std::size_t>(n) + 1, 0.0);
      for (int l = n - 1; l >= 0; --l)
        suffix_[static_cast<std::size_t>(l)] = suffix_[static_cast<std::size_t>(l) + 1] + static_cast<double>(demand[static_cast<std::size_t>(l)]);
      const double slots = static_cast<double>(in.pool_slots);
      const int top = std::clamp(in.coarsest_clamp, 0, n - 1);
      int fit = top;
      for (int c = 0; c <= top; ++c)
        if (suffix_[static_cast<std::size_t>(c)] <= p_.high_water * slots) {
          fit = c;
          break;
        }
      if (fit > clamp_) {
        reason = fmt::format("pool: {} pages wanted from level {} > {:.0f} (high water × {} slots); clamp to {}",
                             suffix_[static_cast<std::size_t>(clamp_)], clamp_, p_.high_water * slots, in.pool_slots, fit);
        clamp_ = fit;
        calm_ = 0;
      } else if (clamp_ > 0 && suffix_[static_cast<std::size_t>(clamp_ - 1)] <= p_.low_water * slots) {
        if (++calm_ >= p_.relax_frames) {
          reason = fmt::format("pool: level {} would need {} pages <= {:.0f} (low water) for {} frames", clamp_ - 1,
                               suffix_[static_cast<std::size_t>(clamp_ - 1)], p_.low_water * slots, p_.relax_frames);
          --clamp_;
          calm_ = 0;
        }
      } else {
        calm_ = 0;
      }
    }
    if (clamp_ > d.clamp) {
      d.clamp = clamp_;
      if (!reason.empty()) d.reason = reason;
    } else if (d.reason.empty()) {
      d.reason = reason;
    }
    return d;
  }

 private:
  ThrottleParams p_;
  std::unique_ptr<IThrottlePolicy> io_;
  int clamp_ = 0;  // the pool's clamp
  int calm_ = 0;
  std::vector<double> suffix_;
};
}  // namespace

std::unique_ptr<IThrottlePolicy> make_throttle_vt_clamp(const ThrottleParams& p) { return std::make_unique<VtClampThrottle>(p); }

}  // namespace vtsim
