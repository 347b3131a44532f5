// No throttling: every level is always requested and sampled (the baseline).
#include "stream/throttle/i_throttle.h"

namespace vtsim {

namespace {
class NoThrottle final : public IThrottlePolicy {
 public:
  const char* name() const override { return "none"; }
  ThrottleDecision update(const ThrottleInput&) override { return {}; }
};
}  // namespace

std::unique_ptr<IThrottlePolicy> make_throttle_none(const ThrottleParams&) { return std::make_unique<NoThrottle>(); }

}  // namespace vtsim
