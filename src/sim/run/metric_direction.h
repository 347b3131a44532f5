#pragma once
// Which way each summary metric is better (docs/metrics.md, "Directions"): one table read by
// `vtsim compare` (its default rules), the report of several runs (`vtsim report`) and the sweep
// report (which colours only metrics with a direction). A metric has a direction only when a
// change that way is better whatever caused it: fewer visible pops or less disk traffic can mean
// that nothing loaded, a higher RAM hit ratio that the pool thrashed, so those have none.
#include <string>
#include <vector>

namespace vtsim {

enum class MetricDirection { lower, higher, neither };

struct MetricDirectionRule {
  const char* pattern;  // '*' matches any run of characters (glob_match, metric_path.h)
  MetricDirection direction;
  const char* why;
};

// The table, in docs/metrics.md's order. A key takes its most specific matching pattern: one
// without '*' first, then the one with more literal characters, then the earlier (compare's rule).
const std::vector<MetricDirectionRule>& metric_direction_rules();

// The direction of a summary key ("latency_ms.p95", "popin.visible_pops"); neither when no
// pattern matches.
MetricDirection metric_direction(const std::string& key);

const char* to_string(MetricDirection d);  // "lower" | "higher" | "neither"

// The keys whose "better" needs the served fraction not to fall and no more tiles throttled
// (latency_ms.* with direction lower, Kaplan–Meier quantiles included: a throttle keeps tiles from
// ever being requested, so even they miss them): a latency over fewer of the wanted tiles is not
// an improvement (docs/metrics.md, "Latency").
bool is_served_latency_key(const std::string& key);

}  // namespace vtsim
