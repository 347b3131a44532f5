#include "sim/run/metric_direction.h"

#include <algorithm>
#include <cstring>

#include "sim/run/metric_path.h"

namespace vtsim {

const std::vector<MetricDirectionRule>& metric_direction_rules() {
  using D = MetricDirection;
  static const std::vector<MetricDirectionRule> rules = {
      {"latency_ms.*", D::lower, "a tile needed sooner on screen is better"},
      {"latency_ms.*count", D::neither, "how many were measured, not how well"},
      {"latency_ms.tiles", D::neither, "served requests: more can mean more motion"},
      {"latency_ms.from_ram_cache", D::neither, "a count, not a speed"},
      {"latency_ms.requests", D::neither, "demand requests: more can mean more motion"},
      {"latency_ms.served_fraction", D::higher, "a request served in the run is better than one never served"},
      {"latency_ms.censored.*", D::neither, "requests never served and their waits: read with the served fraction"},
      {"latency_ms.km.*", D::lower, "Kaplan-Meier quantiles count the unserved requests too"},
      {"popin.*", D::lower, "less blur, a smaller deficit, sharp sooner"},
      {"popin.visible_pops", D::neither, "fewer pops can mean nothing sharpened (a starved pool)"},
      {"popin.measured_frames", D::neither, "a count of frames"},
      {"popin.time_to_sharp_s.events", D::neither, "a property of the trace"},
      {"bandwidth.*", D::neither, "more costs IO; less can mean less was loaded"},
      {"bandwidth.wasted.*", D::lower, "work paid for nothing"},
      {"cache.*", D::neither, "counts of the caches' work"},
      {"cache.ram_hit_ratio", D::neither, "higher when the pool thrashes and re-requests what RAM holds"},
      {"cache.prefetch_hits", D::higher, "demand served by a look-ahead fetch"},
      {"cache.*evict*", D::lower, "work redone later"},
      {"cache.*thrash", D::lower, "evicted then needed again soon"},
      {"throttle.frames_throttled", D::lower, "frames held coarser than wanted"},
      {"throttle.requests_throttled", D::lower, "tiles wanted and never requested"},
      {"throttle.max_clamp", D::lower, "the coarsest the screen was held to"},
      {"faults.*", D::lower, "failed reads and decodes"},
      {"startup.first_sharp_s", D::lower, "the start-up fill's length"},
  };
  return rules;
}

namespace {
std::size_t literal_chars(const char* p) { return std::strlen(p) - static_cast<std::size_t>(std::count(p, p + std::strlen(p), '*')); }
}  // namespace

MetricDirection metric_direction(const std::string& key) {
  const MetricDirectionRule* best = nullptr;
  for (const MetricDirectionRule& r : metric_direction_rules()) {
    if (!glob_match(r.pattern, key)) continue;
    if (!best) {
      best = &r;
      continue;
    }
    const bool r_exact = std::strchr(r.pattern, '*') == nullptr, b_exact = std::strchr(best->pattern, '*') == nullptr;
    if (r_exact != b_exact) {
      if (r_exact) best = &r;
      continue;
    }
    if (literal_chars(r.pattern) > literal_chars(best->pattern)) best = &r;
  }
  return best ? best->direction : MetricDirection::neither;
}

const char* to_string(MetricDirection d) {
  switch (d) {
    case MetricDirection::lower: return "lower";
    case MetricDirection::higher: return "higher";
    default: return "neither";
  }
}

bool is_served_latency_key(const std::string& key) {
  return key.rfind("latency_ms.", 0) == 0 && metric_direction(key) == MetricDirection::lower;
}

}  // namespace vtsim
