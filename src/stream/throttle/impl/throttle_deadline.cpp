// MaxTextureLOD by deadline (Yao 2007 §4-4: "when the camera outruns updates, clamp the finest
// level used — for uploads and sampling; in the extreme use the pyramid only, so any speed stays
// smooth").
//
// The pipeline serves coarse before fine, so level l is complete only after every coarser missing
// byte: eta(l) = sum_{k >= l} missing(k) / service. The camera *outruns* the updates when the
// requested backlog (levels at or above the clamp) exceeds the deadline and does not drain below
// it within drain_horizon_s at its current rate of change (smoothed over ~relax_frames frames).
// That covers a growing backlog and a saturated one (whole windows missing while the camera keeps
// moving: it neither grows nor drains). Jumps that are not speed — the first frame, a cut, the
// clamp itself changing what is requested — are left out of the rate, so a backlog that is large
// but draining (the first fill, a teleport) does not clamp: coarse-before-fine priority already
// shows the coarse levels first.
//
// Engage: clamp to the finest level whose eta fits the deadline (the pyramid if none). Relax,
// after relax_frames consecutive frames without growth, to the finest level whose eta fits
// deadline × relax_factor, or by one level once nothing is missing at or above the clamp (so a
// finer level whose first fill alone exceeds the deadline still gets its turn).
#include <fmt/format.h>

#include "stream/throttle/i_throttle.h"

namespace vtsim {

namespace {
class DeadlineThrottle final : public IThrottlePolicy {
 public:
  explicit DeadlineThrottle(const ThrottleParams& p) : p_(p) {}
  const char* name() const override { return "deadline"; }

  ThrottleDecision update(const ThrottleInput& in) override {
    const int n = static_cast<int>(in.missing_bytes_by_level.size());
    eta_.assign(static_cast<std::size_t>(n) + 1, 0.0);
    double bytes = 0.0;
    for (int l = n - 1; l >= 0; --l) {
      bytes += static_cast<double>(in.missing_bytes_by_level[static_cast<std::size_t>(l)]);
      eta_[static_cast<std::size_t>(l)] = in.service_Bps > 0 ? bytes / in.service_Bps : 0.0;
    }
    const double deadline_s = p_.deadline_ms * 1e-3;
    const int from = std::min(std::max(clamp_, in.finest_needed), n);
    const double requested = from < n ? eta_[static_cast<std::size_t>(from)] : 0.0;  // seconds of work

    // Growth of the requested backlog, in seconds of work per second, smoothed (EWMA over
    // ~relax_frames frames); discontinuities are skipped.
    if (in.discontinuity) {
      growth_ = 0.0;  // a jump, not speed: the rate is measured afresh after it
      samples_ = 0;
    } else if (have_prev_ && from == prev_from_) {
      const double rate = (requested - prev_requested_) / in.frame_period_s;
      const double a = 2.0 / (p_.relax_frames + 1.0);
      growth_ = samples_ == 0 ? rate : growth_ + a * (rate - growth_);
      ++samples_;
    }
    have_prev_ = true;
    prev_requested_ = requested;
    prev_from_ = from;

    // Seconds until the backlog is back under the deadline at the current rate (inf: not draining).
    const double drain_s = growth_ < 0.0 ? (requested - deadline_s) / -growth_ : 1e300;
    const bool outrun = requested > deadline_s && samples_ >= p_.relax_frames && drain_s > p_.drain_horizon_s;

    ThrottleDecision d;
    if (outrun && clamp_ < in.coarsest_clamp) {
      int target = in.coarsest_clamp;
      for (int l = clamp_ + 1; l < in.coarsest_clamp && l < n; ++l)
        if (eta_[static_cast<std::size_t>(l)] <= deadline_s) {
          target = l;
          break;
        }
      d.reason = fmt::format("engage: backlog from level {} needs {:.0f} ms > deadline {:.0f} ms and {}", from,
                             requested * 1e3, p_.deadline_ms,
                             growth_ >= 0.0 ? std::string("does not drain")
                                            : fmt::format("drains too slowly ({:.1f} s)", drain_s));
      set_clamp(target);
    } else if (clamp_ > 0 && !outrun && growth_ <= 0.0) {
      int relax_to = clamp_;
      while (relax_to > 0 && eta_[static_cast<std::size_t>(relax_to - 1)] <= deadline_s * p_.relax_factor) --relax_to;
      const bool caught_up = requested == 0.0;
      if (relax_to < clamp_ || caught_up) {
        if (++calm_frames_ >= p_.relax_frames) {
          if (relax_to == clamp_) {
            d.reason = fmt::format("relax: caught up at level {} for {} frames", clamp_, p_.relax_frames);
            --relax_to;
          } else {
            d.reason = fmt::format("relax: backlog from level {} needs {:.0f} ms <= {:.0f} ms for {} frames", relax_to,
                                   eta_[static_cast<std::size_t>(relax_to)] * 1e3, deadline_s * p_.relax_factor * 1e3,
                                   p_.relax_frames);
          }
          set_clamp(relax_to);
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
  void set_clamp(int c) {
    clamp_ = c;
    calm_frames_ = 0;
    growth_ = 0.0;  // what is requested changed: measure its rate afresh
    samples_ = 0;
    have_prev_ = false;
  }

  ThrottleParams p_;
  int clamp_ = 0;
  int calm_frames_ = 0;
  double growth_ = 0.0;  // smoothed d(requested)/dt, seconds of work per second
  int samples_ = 0;
  bool have_prev_ = false;
  double prev_requested_ = 0.0;
  int prev_from_ = 0;
  std::vector<double> eta_;
};
}  // namespace

std::unique_ptr<IThrottlePolicy> make_throttle_deadline(const ThrottleParams& p) {
  return std::make_unique<DeadlineThrottle>(p);
}

}  // namespace vtsim
