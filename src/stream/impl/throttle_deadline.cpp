// MaxTextureLOD by deadline (seed 000 §4-4). The pipeline serves coarse before fine, so level l
// is complete only after every coarser missing byte: eta(l) = sum_{k >= l} missing(k) / service.
// The clamp is the finest level whose eta fits the deadline ("when the camera outruns updates,
// clamp the finest level used — for uploads and sampling"); if none fits, the pyramid only ("in
// the extreme use the pyramid only, so any speed stays smooth"). Engaging is immediate; relaxing
// goes one level at a time, after the finer level's eta has fitted deadline × relax_factor for
// relax_frames consecutive frames, so the clamp does not oscillate.
#include <fmt/format.h>

#include "stream/i_throttle.h"

namespace vtsim {

namespace {
class DeadlineThrottle final : public IThrottlePolicy {
 public:
  explicit DeadlineThrottle(const ThrottleParams& p) : p_(p) {}
  const char* name() const override { return "deadline"; }

  ThrottleDecision update(const ThrottleInput& in) override {
    const int n = static_cast<int>(in.missing_bytes_by_level.size());
    // eta_s[l]: seconds to serve levels >= l (coarse first).
    eta_.assign(static_cast<std::size_t>(n) + 1, 0.0);
    double bytes = 0.0;
    for (int l = n - 1; l >= 0; --l) {
      bytes += static_cast<double>(in.missing_bytes_by_level[static_cast<std::size_t>(l)]);
      eta_[static_cast<std::size_t>(l)] = in.service_Bps > 0 ? bytes / in.service_Bps : 0.0;
    }
    const double deadline_s = p_.deadline_ms * 1e-3;
    int target = in.coarsest_clamp;
    for (int l = 0; l < in.coarsest_clamp && l < n; ++l)
      if (eta_[static_cast<std::size_t>(l)] <= deadline_s) {
        target = l;
        break;
      }
    ThrottleDecision d;
    d.clamp = clamp_;
    if (target > clamp_) {
      d.reason = fmt::format("engage: backlog of level {} needs {:.0f} ms > deadline {:.0f} ms", clamp_,
                             eta_[static_cast<std::size_t>(std::min(clamp_, n - 1))] * 1e3, p_.deadline_ms);
      clamp_ = target;
      calm_frames_ = 0;
    } else if (clamp_ > 0 && target < clamp_) {
      const double finer = eta_[static_cast<std::size_t>(clamp_ - 1)];
      if (finer <= deadline_s * p_.relax_factor) {
        if (++calm_frames_ >= p_.relax_frames) {
          d.reason = fmt::format("relax: backlog of level {} needs {:.0f} ms <= {:.0f} ms for {} frames",
                                 clamp_ - 1, finer * 1e3, deadline_s * p_.relax_factor * 1e3, p_.relax_frames);
          --clamp_;
          calm_frames_ = 0;
        }
      } else {
        calm_frames_ = 0;
      }
    } else {
      calm_frames_ = 0;
    }
    d.clamp = clamp_;
    return d;
  }

 private:
  ThrottleParams p_;
  int clamp_ = 0;
  int calm_frames_ = 0;
  std::vector<double> eta_;
};
}  // namespace

std::unique_ptr<IThrottlePolicy> make_throttle_deadline(const ThrottleParams& p) {
  return std::make_unique<DeadlineThrottle>(p);
}

}  // namespace vtsim
