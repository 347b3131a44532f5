#pragma once
// Each tile's life on a timeline (`vtsim replay --timeline FILE`, docs/metrics.md "A tile's life
// on the timeline"): every demand request's stages with their times — request, queue, read,
// decode wait, decode (or produce), upload wait, upload, first sampled, evicted — recorded while a
// replay runs (either clock) and written as Chrome's Trace Event JSON, which Perfetto
// (ui.perfetto.dev) and chrome://tracing open. One process per stage; within it one track (lane)
// per request under way at once (a slice goes to the lowest free lane), so overlapping tiles never
// share a track; a flow arrow from each request's first stage to its first sampled frame.
//
// The recorder observes the pipeline (stream/exec/pipeline_observer.h: requests, jobs, unserved
// ends), the uploads and the system's VRAM evictions and sample marks (SystemRun calls it: the
// frame loop pays a null check per hook when no timeline is asked for). Simulated clock: the file
// is a function of the trace and config only (byte-identical run to run). Real clock: wall times.
#include <cstdint>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/tile_key.h"
#include "core/time.h"
#include "sim/run/replay_config.h"
#include "stream/exec/pipeline.h"
#include "stream/exec/pipeline_observer.h"

namespace vtsim {

class IStreamingSystem;

// One demand request's life (ticks since the run started; -1: stage not reached).
struct TileLife {
  std::uint64_t id = 0;   // 1, 2, ... in request order (the flow arrow's id)
  TileKey key;
  int frame = 0;          // the frame that requested it
  Ticks request = 0;
  bool ram_hit = false, produced = false;
  Ticks read_start = -1, read_end = -1;      // the job that brought it (the last, after retries)
  Ticks decode_start = -1, decode_end = -1;  // a produced tile: production
  int jobs = 0;                              // jobs run for it (retries, re-reads after a cancel)
  Ticks in_ram = -1;                         // ready, waiting for the upload budget
  Ticks upload_start = -1, upload_end = -1;  // the frame's upload, then the link's transfer time
  int upload_frame = -1;
  bool stale = false;                        // uploaded, refused by the system (no longer wanted there)
  Ticks sampled = -1;                        // first sampled: the start of the frame that drew it
  int sampled_frame = -1;
  Ticks evicted = -1;                        // its VRAM slot went to another tile
  int evicted_frame = -1;
  Ticks ended = -1;                          // unserved: when it stopped being needed or failed
  Unserved why = Unserved::open_at_end;      // with ended
  std::uint64_t bytes = 0;                   // decoded bytes uploaded
  bool done = false;                         // ended: sampled, evicted, left VRAM, stale or unserved
};

struct TimelineOptions {
  int first_frame = 0;                                  // --timeline-frames A:B (inclusive)
  int last_frame = std::numeric_limits<int>::max();
  std::uint64_t max_bytes = 100'000'000;                // --timeline-max-MB: the file's bound
};

// Parses "A:B" (frames A to B inclusive, A <= B, both >= 0; "A:" to the end). Throws InputError
// naming `flag`.
void parse_timeline_frames(const std::string& flag, const std::string& text, TimelineOptions& out);

// The size bound, checked before a run: `frames` frames in the range, each bringing at most the
// upload budget's tiles (upload.tiles_per_frame, or upload.bytes_per_frame over the smallest
// tile; 64 tiles when neither limits), each tile life at most kTimelineLifeBytes. That is the
// steady state's bound; a start-up fill or a cut requests more tiles in one frame, so the recorder
// also checks the bound at each frame's end (end_frame throws the same InputError).
inline constexpr std::uint64_t kTimelineLifeBytes = 1600;  // a life's events and their lanes' names, upper bound (docs/metrics.md)
inline constexpr std::uint64_t kTimelineFrameBytes = 160;  // a frame's own slice
inline constexpr std::uint64_t kTimelineJobBytes = 720;    // a job's read, decode wait and decode slices
inline constexpr std::uint64_t kTimelineEvictionBytes = 160;
struct TimelineEstimate {
  std::uint64_t tiles_per_frame = 0;
  std::uint64_t bytes_per_frame = 0;
  std::uint64_t bytes = 0;
  std::uint64_t max_frames = 0;  // the most frames that fit the bound
  std::string budget;            // which budget set tiles_per_frame
};
TimelineEstimate estimate_timeline(const ReplayConfig& cfg, int frames, const TimelineOptions& opt);
// Throws InputError("--timeline", ...) when the estimate passes the bound: the bound, the
// estimate, and how to narrow it (--timeline-frames with the frames that fit, --timeline-max-MB).
void check_timeline_bound(const ReplayConfig& cfg, int frames, const TimelineOptions& opt);

class TimelineRecorder final : public IPipelineObserver {
 public:
  explicit TimelineRecorder(TimelineOptions opt = {}) : opt_(opt) {}

  // IPipelineObserver.
  void on_request(TileKey key, int frame, Ticks now, bool ram_hit, bool produced) override;
  void on_job(const JobResult& r, bool prefetch, bool produced) override;
  void on_unserved(TileKey key, Ticks end, Unserved why) override;

  // SystemRun: the run's frame period and clock; each planned upload after the frame's commit
  // (`accepted`: the system took it; else stale), then the frame's end (evictions logged by the
  // system into evictions(), first samples asked of the system after the pop-in measurement).
  void begin_run(double period_s, std::string clock, std::string trace_name);
  void begin_frame(int frame, Ticks now) {
    frame_ = frame;
    now_ = now;
  }
  void on_upload(const UploadItem& u, int frame, Ticks now, Ticks transfer, bool accepted);
  // After the frame's commit, each planned upload: one not reported accepted this frame was stale.
  void on_upload_if_stale(const UploadItem& u, int frame, Ticks now) {
    const TileLife* l = open_life(u.key);
    if (l && l->upload_frame != frame) on_upload(u, frame, now, 0, false);
  }
  std::vector<TileKey>* eviction_log() { return &evict_log_; }
  void end_frame(int frame, Ticks now, const IStreamingSystem& system, bool measured, double blurry_fraction);

  // The Trace Event JSON (deterministic for equal records). Throws InputError("--timeline") when
  // it passes opt.max_bytes.
  std::string json() const;

  const std::vector<TileLife>& lives() const { return lives_; }
  struct FrameMark {
    int frame = 0;
    Ticks start = 0;
    bool measured = false;
    double blurry = 0.0;  // blurry fraction of the measured frame
  };
  const std::vector<FrameMark>& frames() const { return frames_; }
  double period_s() const { return period_s_; }
  // Counts of what the JSON holds (each equals a summary counter over the frames recorded).
  struct Counts {
    std::uint64_t requests = 0, reads = 0, decodes = 0, produced = 0, uploads = 0, evictions = 0, first_sampled = 0;
  };
  Counts counts() const;

 private:
  bool in_range(int frame) const { return frame >= opt_.first_frame && frame <= opt_.last_frame; }
  TileLife* open_life(TileKey key);
  void close(TileLife& life);

  TimelineOptions opt_;
  double period_s_ = 1.0 / 60.0;
  std::string clock_ = "simulated", trace_name_;
  int frame_ = 0;
  Ticks now_ = 0;
  std::vector<TileLife> lives_;
  std::unordered_map<TileKey, std::size_t, TileKeyHash> open_;  // key -> its life, until it ends
  struct Job {  // every job the executor returned (of a recorded life, or completed in the range)
    JobResult r;
    std::uint64_t life = 0;  // 0: no recorded life (a look-ahead prefetch, or requested before the range)
    bool prefetch = false, produced = false;
    int frame = 0;           // the frame that collected it
  };
  std::vector<Job> jobs_;
  struct Eviction {
    TileKey key;
    int frame = 0;
    Ticks t = 0;
    std::uint64_t life = 0;  // 0: its life is not recorded
  };
  std::vector<Eviction> evictions_;
  std::vector<TileKey> evict_log_;
  std::vector<std::size_t> pending_;  // lives uploaded, not sampled yet
  std::vector<FrameMark> frames_;
};

}  // namespace vtsim
