#pragma once
// Throttling / residency policies: given the backlog and what the device can serve, decide the
// MaxTextureLOD clamp (the finest level requested and sampled; Yao 2007 §4-4) and, for virtual
// textures, a feedback LOD bias. One policy per file in stream/throttle/impl/, registered by one line in
// stream/throttle/throttle_registry.cpp. docs/pipeline.md, "MaxTextureLOD throttling".
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "core/registry.h"
#include "core/time.h"

namespace vtsim {

// The config's [throttle] section.
struct ThrottleParams {
  std::string policy = "deadline"; // which policy (throttle_policies())
  double deadline_ms = 250.0;   // a level whose backlog takes longer than this to serve is clamped
  double relax_factor = 0.5;    // relax one level once the finer backlog fits in deadline × this ...
  int relax_frames = 15;        // ... for this many consecutive frames (hysteresis)
  double drain_horizon_s = 1.0; // a backlog over the deadline that will not drain below it within
                                // this long is the camera outrunning updates, not a transient
  // Virtual-texture residency policies (issue 5) read the pool fields below.
  double high_water = 0.95;     // pool occupancy above which the feedback bias rises
  double low_water = 0.75;      // pool occupancy below which it falls
  double bias_step = 0.25;      // bias change per adjustment, levels
  double max_bias = 4.0;        // bias clamp, levels
  double adjust_rate = 0.2;     // Unreal: bias change per unit of residency beyond a bound, per frame
};

struct ThrottleInput {
  int frame = 0;
  Ticks now = 0;
  double frame_period_s = 1.0 / 60.0;
  int num_levels = 1;
  int finest_needed = 0;        // finest level any visible sample wants this frame
  int coarsest_clamp = 0;       // the most the clamp may rise: the clip pyramid ("pyramid only")
  // Bytes each level still misses, as if unclamped (resident excluded; in flight included).
  std::vector<std::uint64_t> missing_bytes_by_level;
  double service_Bps = 0.0;     // bytes/s the pipeline can bring into VRAM (its bottleneck); 0 = unlimited
  bool discontinuity = false;   // first frame or a cut: the backlog jumps for reasons other than speed
  // Virtual texturing: physical pool state.
  double pool_occupancy = 0.0;  // fraction of pool slots holding pages used in the last frames
  double pool_pressure = 0.0;   // wanted pages / pool slots (> 1: oversubscribed)
  // Pages the view wants per level (desired pages and their ancestors, under the current bias,
  // not clamped) and the pool's slots: what a clamp must fit (empty / 0 for clipmaps).
  std::vector<std::uint64_t> pool_demand_by_level;
  std::uint64_t pool_slots = 0;
};

struct ThrottleDecision {
  int clamp = 0;                // finest level allowed (0 = unthrottled)
  double bias = 0.0;            // feedback LOD bias, levels (virtual texturing)
  double sample_bias = 0.0;     // LOD bias the screen samples with (Unreal's residency bias is
                                // also a sampling bias; RAGE's feedback bias is not)
  std::string reason;           // why it changed (empty when unchanged)
};

class IThrottlePolicy {
 public:
  virtual ~IThrottlePolicy() = default;
  virtual const char* name() const = 0;
  virtual ThrottleDecision update(const ThrottleInput& in) = 0;
  // Whether update() may ever return a feedback bias (a VT system then reads every sample): a
  // sweep stepping systems on threads renders the samples up front for such a group.
  virtual bool may_bias() const { return false; }
};

struct ThrottlePolicyInfo {
  std::string_view name;
  std::string_view why;
  std::unique_ptr<IThrottlePolicy> (*make)(const ThrottleParams&);
};

// The policies, one line each in stream/throttle/throttle_registry.cpp.
const Registry<ThrottlePolicyInfo>& throttle_policies();
// The policy p.policy names, with p. Throws std::invalid_argument (Registry::at) for an unknown name.
std::unique_ptr<IThrottlePolicy> make_throttle_policy(const ThrottleParams& p);

}  // namespace vtsim
