// The one table of throttling/residency policies: adding a policy is one file in impl/ and one
// line here.
#include "stream/throttle/i_throttle.h"

namespace vtsim {

std::unique_ptr<IThrottlePolicy> make_throttle_none(const ThrottleParams&);
std::unique_ptr<IThrottlePolicy> make_throttle_deadline(const ThrottleParams&);
std::unique_ptr<IThrottlePolicy> make_throttle_vt_clamp(const ThrottleParams&);
std::unique_ptr<IThrottlePolicy> make_throttle_unreal_bias(const ThrottleParams&);
std::unique_ptr<IThrottlePolicy> make_throttle_rage_watermarks(const ThrottleParams&);

const Registry<ThrottlePolicyInfo>& throttle_policies() {
  static const Registry<ThrottlePolicyInfo> table(
      "throttle policy",
      {
          {"none", "never clamp: every level requested and sampled", make_throttle_none},
          {"deadline", "MaxTextureLOD (Yao 2007 §4-4): clamp levels whose backlog misses the deadline", make_throttle_deadline},
          {"vt_clamp", "VT MaxTextureLOD: the deadline clamp, or coarser until the wanted pages fit the pool", make_throttle_vt_clamp},
          {"unreal_bias", "VT: Unreal's residency mip bias, proportional to visible residency beyond its bounds", make_throttle_unreal_bias},
          {"rage_watermarks", "VT: RAGE's global feedback bias, stepped at high/low water marks of pool pressure", make_throttle_rage_watermarks},
      });
  return table;
}

std::unique_ptr<IThrottlePolicy> make_throttle_policy(const ThrottleParams& p) {
  return throttle_policies().at(p.policy).make(p);
}

}  // namespace vtsim
