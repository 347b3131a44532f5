#pragma once
// Metrics of a replay, defined once in docs/metrics.md: latency (with its stage breakdown),
// pop-in, bandwidth, cache, throttle, and the run's own cost. The collector takes per-frame rows
// and per-tile upload records; summary() turns them into the summary JSON, write_frames_csv() the
// per-frame CSV. Percentiles are nearest-rank on the sorted values (deterministic).
#include <array>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/time.h"
#include "stream/exec/pipeline.h"
#include "stream/system/i_system.h"

namespace vtsim {

struct FrameRow {
  int frame = 0;
  double t_s = 0.0;
  int clamp = 0;                    // MaxTextureLOD clamp in force
  double bias = 0.0;                // feedback LOD bias (virtual texturing)
  bool measured = false;            // pop-in measured this frame (feedback rendered)
  std::uint32_t samples = 0;        // measurement samples on textured surfaces
  std::uint32_t blurry = 0;         // samples with resident level - desired level >= 1
  double deficit_sum = 0.0;         // sum over samples of max(0, resident - desired)
  std::uint32_t pops = 0;           // samples that sharpened by >= 1 level this frame
  int finest_needed = 0;            // finest desired level of any sample
  bool event = false;               // a cut or fast turn starts at this frame
  std::uint64_t disk_bytes = 0;     // read this frame (completed reads)
  std::uint64_t decoded_bytes = 0;
  std::uint64_t upload_bytes = 0;
  std::uint32_t uploads = 0;
  std::uint32_t needs = 0;          // tiles needed and not resident
  std::uint32_t live_requests = 0;  // requests in the pipeline (queued, in flight, waiting upload)
  std::uint64_t ram_bytes = 0;      // RAM cache occupancy
  std::uint32_t throttled_needs = 0;  // tiles the clamp kept from being requested
  SystemCounters system{};          // system-specific counters (MetricsCollector::set_system_columns)
  std::uint32_t produced = 0;       // produced tiles completed this frame (the produce stage)
  double produce_ms = 0.0;          // their production time, ms

  bool operator==(const FrameRow&) const = default;
};

struct TileLatency {
  Ticks needed = 0;         // first needed (a request needed before metrics.warmup_s is the start-up fill's)
  Ticks total = 0;          // first needed -> resident and sampled
  int frames = 0;
  Ticks queue = 0, io = 0, decode_wait = 0, decode = 0, upload_wait = 0, upload = 0;
  std::uint8_t level = 0;
  bool ram_hit = false;
};

// The latency of an upload committed at `now` in `frame`, from what its UploadItem carries (each
// stage's ticks); `upload` is the copy's own time (the simulated link; 0 where the client times it
// elsewhere, as the GL client's GPU copy).
TileLatency upload_latency(const UploadItem& u, Ticks now, int frame, Ticks upload);

// Kaplan–Meier (1958) quantiles of a time to an event, with right-censored observations: S(t) =
// Π over event times t_i <= t of (1 − d_i / n_i) (d_i events at t_i, n_i still at risk; at a tie
// events come before censorings); the q-quantile is the smallest event time with 1 − S >= q, or
// nullopt when S never falls that far (too many censored before). Without censoring it equals the
// nearest-rank percentile.
std::vector<std::optional<double>> km_quantiles(std::vector<double> events, std::vector<double> censored,
                                                const std::vector<double>& qs);

struct Percentiles {
  double p50 = 0, p95 = 0, p99 = 0, max = 0, mean = 0;
  std::size_t count = 0;
};
Percentiles percentiles(std::vector<double> v);
nlohmann::json to_json(const Percentiles& p);

struct ThrottleChange {
  int frame = 0;
  double t_s = 0.0;
  int from = 0, to = 0;
  double bias = 0.0;
  std::string reason;
};

class MetricsCollector {
 public:
  void add_frame(const FrameRow& r) { frames_.push_back(r); }
  void add_latency(const TileLatency& l) { latencies_.push_back(l); }
  // A demand request that ended unserved (cancelled, failed, stale, open at the end): censored.
  void add_unserved(const UnservedRequest& u) { unserved_.push_back(u); }
  // metrics.warmup_s: frames before it and requests first needed before it are left out of the
  // steady-state figures (latency, pop-in, per-frame uploads, throttle counts); startup_json
  // reports them. 0: nothing is left out.
  void set_warmup_s(double s) { warmup_s_ = s; }
  double warmup_s() const { return warmup_s_; }
  void add_throttle_change(const ThrottleChange& c) { throttle_.push_back(c); }
  void add_level_bytes(int level, std::uint64_t disk, std::uint64_t upload);
  // Names of the system-specific CSV columns appended after the standard ones (at most
  // kSystemCounters; throws std::invalid_argument beyond).
  void set_system_columns(std::vector<std::string> names);

  const std::vector<FrameRow>& frames() const { return frames_; }
  const std::vector<TileLatency>& latencies() const { return latencies_; }
  const std::vector<UnservedRequest>& unserved() const { return unserved_; }
  const std::vector<ThrottleChange>& throttle_changes() const { return throttle_; }
  // Names of FrameRow::system's columns (set_system_columns), in order.
  const std::vector<std::string>& system_columns() const { return system_columns_; }

  // Pop-in, latency, bandwidth-per-frame and throttle sections; `duration_s` averages rates.
  nlohmann::json latency_json() const;
  nlohmann::json popin_json(double sharp_margin) const;
  nlohmann::json upload_per_frame_json() const;
  nlohmann::json per_level_json(double duration_s) const;
  nlohmann::json throttle_json(std::size_t max_changes = 200) const;
  // The start-up fill (docs/metrics.md, "Start-up"): warmup_s, its frames, tiles uploaded and disk
  // bytes read in them, the first measured frame whose blurry fraction is within sharp_margin of
  // the steady frames' median (first_sharp_s, null if none) and the tiles uploaded up to it.
  nlohmann::json startup_json(double sharp_margin) const;
  // Bytes read, decoded and uploaded in the steady frames (at or after warmup_s), and their
  // duration: the frames' count × period, s.
  struct SteadyBytes {
    std::uint64_t disk = 0, decoded = 0, upload = 0;
    double duration_s = 0.0;
  };
  SteadyBytes steady_bytes(double duration_s) const;

  void write_frames_csv(const std::string& path) const;

 private:
  std::vector<FrameRow> frames_;
  std::vector<TileLatency> latencies_;
  std::vector<UnservedRequest> unserved_;
  double warmup_s_ = 0.0;
  std::vector<ThrottleChange> throttle_;
  std::vector<std::string> system_columns_;
  std::vector<std::uint64_t> level_disk_, level_upload_;
};

}  // namespace vtsim
