#include "sim/run/run_summary.h"

#include <sys/resource.h>

#include <algorithm>
#include <vector>

#include "sim/run/frame_loop.h"
#include "sim/run/metrics.h"
#include "sim/run/provenance.h"
#include "sim/run/replay_config.h"
#include "sim/run/resources.h"
#include "stream/exec/pipeline.h"
#include "stream/exec/sim_executor.h"
#include "stream/system/i_system.h"

namespace vtsim {

double peak_rss_MB() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return static_cast<double>(ru.ru_maxrss) / 1024.0;  // Linux reports KiB
}

void fill_run_summary(nlohmann::json& s, const SummaryInputs& in) {
  MetricsCollector& m = in.metrics;
  const PipelineCounters& c = in.pipe.counters();
  for (int l = 0; l < in.system.num_levels(); ++l) m.add_level_bytes(l, c.disk_bytes_by_level[static_cast<std::size_t>(l)], in.level_upload[l]);
  const double duration_s = in.plan.duration_s;
  const auto MBps = [&](std::uint64_t bytes) { return static_cast<double>(bytes) / duration_s / 1e6; };
  // Requests that ended unserved, and those still open at the end (censored there).
  std::vector<UnservedRequest> unserved = in.pipe.unserved();
  in.pipe.open_demand_requests(std::max(in.end, seconds_to_ticks(duration_s)), unserved);
  for (const UnservedRequest& u : unserved) m.add_unserved(u);
  // What the run was (docs/metrics.md): the schema, the build, the effective config, the trace.
  s["schema"] = kSummarySchema;
  s["provenance"] = build_json();
  s["config"] = config_json(in.cfg);
  s["system"] = in.cfg.run.system;
  s["clock"] = in.clock;
  s["trace"] = {{"name", in.plan.trace.name},
                {"path", in.plan.trace.source_path},
                {"content_hash", trace_hash_json(in.plan.trace)},
                {"poses", in.plan.input_poses},
                {"poses_duration_s", in.plan.input_duration_s},
                {"frames", in.plan.frames},
                {"duration_s", duration_s},
                {"fps", 1.0 / in.plan.period_s},
                {"image", {in.plan.trace.image_width, in.plan.trace.image_height}}};
  s["bandwidth"] = {
      {"disk_read_MBps", MBps(c.disk_bytes)},
      {"decoded_MBps", MBps(c.decoded_bytes)},
      {"upload_MBps", MBps(c.upload_bytes)},
      {"prefetch_read_MBps", MBps(c.prefetch_disk_bytes)},
      {"disk_read_bytes", c.disk_bytes},
      {"decoded_bytes", c.decoded_bytes},
      {"upload_bytes", c.upload_bytes},
      {"prefetch_read_bytes", c.prefetch_disk_bytes},
      {"disk_reads", c.disk_reads},
      {"uploads", c.uploads},
      {"upload_bytes_per_frame", m.upload_per_frame_json()["bytes"]},
      {"upload_tiles_per_frame", m.upload_per_frame_json()["tiles"]},
      {"per_level", m.per_level_json(duration_s)},
      {"wasted", {{"read_bytes_cancelled_after_io", c.wasted_read_bytes},
                  {"uploaded_bytes_never_sampled", in.system.evicted_unsampled_bytes()},
                  {"cancelled_before_io", c.cancelled_queued},
                  {"cancelled_after_io", c.cancelled_after_read},
                  {"dropped_before_upload", c.dropped_before_upload}}}};
  if (in.cfg.metrics.warmup_s > 0) {  // the steady state's rates: the frames after the warm-up
    const MetricsCollector::SteadyBytes sb = m.steady_bytes(duration_s);
    const auto rate = [&](std::uint64_t bytes) { return sb.duration_s > 0 ? static_cast<double>(bytes) / sb.duration_s / 1e6 : 0.0; };
    s["bandwidth"]["disk_read_MBps"] = rate(sb.disk);
    s["bandwidth"]["decoded_MBps"] = rate(sb.decoded);
    s["bandwidth"]["upload_MBps"] = rate(sb.upload);
  }
  s["latency_ms"] = m.latency_json();
  s["popin"] = m.popin_json(in.cfg.metrics.sharp_margin);
  s["startup"] = m.startup_json(in.cfg.metrics.sharp_margin);
  const double lookups = static_cast<double>(c.ram_hits + c.ram_misses);
  s["cache"] = {{"ram_hit_ratio", lookups > 0 ? static_cast<double>(c.ram_hits) / lookups : 0.0},
                {"ram_hits", c.ram_hits},
                {"ram_misses", c.ram_misses},
                {"ram_evictions", c.ram_evictions},
                {"ram_evicted_bytes", c.ram_evicted_bytes},
                {"ram_thrash", c.ram_thrash},
                {"ram_policy", in.cfg.ram.policy},
                {"prefetch_requests", c.prefetch_requests},
                {"prefetch_hits", c.prefetch_hits},
                {"vram_evictions", in.system.vram_evictions()},
                {"vram_thrash", in.system.vram_thrash()},
                {"requests", c.requests},
                {"needs", c.needs}};
  s["throttle"] = m.throttle_json();
  s["throttle"]["policy"] = in.cfg.throttle.policy;
  s["faults"] = {{"faults", c.faults},
                 {"retries", c.retries},
                 {"failed_tiles", c.failed_tiles},
                 {"io_error", c.fault_by_kind[static_cast<int>(Fault::io_error)]},
                 {"short_read", c.fault_by_kind[static_cast<int>(Fault::short_read)]},
                 {"checksum", c.fault_by_kind[static_cast<int>(Fault::checksum)]},
                 {"decode_error", c.fault_by_kind[static_cast<int>(Fault::decode_error)]},
                 {"bad_record", c.fault_by_kind[static_cast<int>(Fault::bad_record)]}};
  if (c.produce_requests > 0) {
    const SimExecutor* sim = in.sim;
    s["produce"] = {{"requests", c.produce_requests},
                    {"submitted", c.produce_submitted},
                    {"produced", c.produced},
                    {"produced_bytes", c.produced_bytes},
                    {"production_ms", static_cast<double>(c.produce_ns) * 1e-6},
                    {"mean_ms_per_tile", c.produced ? static_cast<double>(c.produce_ns) * 1e-6 / static_cast<double>(c.produced) : 0.0},
                    {"deferred_by_budget", c.produce_deferred},
                    {"cancelled_before_start", c.produce_cancelled},
                    {"busy_ms", sim ? ticks_to_ms(sim->produce_busy_ticks()) : 0.0}};
  }
  s[in.cfg.run.system] = in.system.stats_json();
  s["resources"] = resources_json(in.cfg, in.system, s[in.cfg.run.system], m);
}

}  // namespace vtsim
