#pragma once
// The frame loop in steps (docs/architecture.md, "The frame loop"). A replay is
//   FramePlan    the trace resampled to run.fps, each frame's time, the frames that render;
//   ViewStream   the view: each frame's feedback and pop-in buffers, rendered in the loop or
//                ahead on worker threads (render_ahead.h), in frame order;
//   SystemRun    one streaming system with its request pipeline, throttle policy and metrics,
//                stepped frame by frame on the view: begin_frame (completions up to the frame's
//                time), step (the system, the throttle, needs, dispatch, uploads within the
//                budget, pop-in, one metrics row), summarize.
// The view is a function of the trace, the scene and the [view] section only, so one ViewStream
// can feed several SystemRuns in lockstep (configs that differ elsewhere): each system reads the
// same buffers and keeps its own state. run_replay (replay.h) is one view and one system.
//
// Per frame, in this order: now = the frame's time (the real clock paces it); run.begin_frame(f,
// now); view.frame(f, any run's keep_samples()); run.step(view). Thread-safety: single-threaded
// (the loop), but for render-ahead's workers behind ViewStream.
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/trace.h"
#include "core/view_spans.h"
#include "sim/run/metrics.h"
#include "sim/run/popin.h"
#include "sim/run/popin_share.h"
#include "sim/run/replay_config.h"
#include "stream/exec/i_executor.h"
#include "stream/exec/pipeline.h"
#include "stream/runtime/streaming_runtime.h"

namespace vtsim {

class IScene;
class IStreamingSystem;
class IThrottlePolicy;
class RenderAhead;
class SimExecutor;
class TimelineRecorder;

// Each cache level's access sequence during a replay (opt-in: ReplayEnv::accesses), what the
// offline simulator, Belady's bound and miss-ratio curves replay (cache/policy/access.h).
//   ram:  one Access per RAM lookup of a demand request, size = the tile's decoded bytes; as many
//         as the summary's cache.ram_hits + cache.ram_misses.
//   pool: one Access per wanted page (at or above the clamp) per frame, size 1; as many as the
//         summary's vt.pool.hits + vt.pool.misses; empty for a system without a pool.
// frame_start has one entry per frame of the replay in both.
struct FramePlan;
struct FrameView;

struct AccessLogs {
  AccessLog ram;
  AccessLog pool;
};

struct ReplayEnv {
  // The real clock: an executor doing real IO and decode, and a pacer that waits until a frame's
  // target time (ticks since start) and returns the actual time the frame starts. Both null: the
  // simulated clock from the config's device models.
  IExecutor* executor = nullptr;
  std::function<Ticks(int frame, Ticks target)> pace;
  // Per-tile sizes; null: from the config's layer formats and compression ratios.
  TileSizer sizer;
  // Called after each uploaded tile with its VRAM slot (IStreamingSystem::vram_slot; real clock:
  // copy into the VRAM arena).
  std::function<void(const UploadItem&, std::int64_t slot)> on_upload;
  // Called once with the system as constructed, before frame 0 (real clock: hand the terrain's
  // decals to its producer).
  std::function<void(IStreamingSystem&)> on_start;
  // Called once after the last frame with the system as it ended (real clock: check VRAM).
  std::function<void(const IStreamingSystem&)> on_finish;
  // Progress callback (frame, frames), called about once a second of wall time.
  std::function<void(int, int)> progress;
  // Called with each frame's view after it is taken, before the systems step on it
  // (`--record-feedback`: the feedback trace of the run, sim/run/feedback_replay.h).
  std::function<void(const FramePlan&, const FrameView&)> on_view;
  std::string clock_name = "simulated";
  // Non-null: each level's access sequence is appended here (AccessLogs). Null: nothing is
  // recorded and nothing is paid.
  AccessLogs* accesses = nullptr;
  // Non-null: every tile request's stages are recorded here (`--timeline`, timeline.h). Null: the
  // loop pays a null check per hook.
  TimelineRecorder* timeline = nullptr;
};

struct ReplayResult {
  nlohmann::json summary;
  MetricsCollector metrics;
};

// The frames of a replay.
struct FramePlan {
  Trace trace;                     // resampled to run.fps (as given for run.fps = 0)
  std::size_t input_poses = 0;     // poses of the trace as given, before resampling
  double input_duration_s = 0.0;   // its last pose time − its first, s
  int frames = 0;
  double t0_s = 0.0;               // trace time of frame 0
  double period_s = 1.0 / 60.0;    // frame period (run.fps = 0: the trace's mean)
  double duration_s = 0.0;         // last frame's time + one period
  // Frames that render feedback: every view.feedback_every-th frame, unless its pose equals the
  // last rendered one (position, orientation, field of view), whose buffers it then reuses.
  std::vector<int> render_frames;
  int feedback_every = 1;

  Ticks target(int f) const { return seconds_to_ticks(trace.poses[static_cast<std::size_t>(f)].t_s - t0_s); }
  // Pop-in is measured at the frames that would render (rendered or reusing the same pose).
  bool measured(int f) const { return f % feedback_every == 0; }
};
// Throws InputError for a trace without poses.
FramePlan plan_frames(const ReplayConfig& cfg, const Trace& trace);

// The feedback pass's view parameters at frame f: the [view] section's, with the GPU model's sample
// within each feedback tile that view.feedback_sampling gives (sequence: feedback_tile_offset of f,
// sim/view/gpu_model.h; middle: −1).
ViewParams feedback_params(const ViewConfig& v, int frame);

// What frame f sees: the same for every system on the view.
struct FrameView {
  int frame = 0;
  const Pose* pose = nullptr;
  bool fresh = false;              // the buffers were rendered at this frame
  bool measured = false;           // pop-in is measured at this frame (FramePlan::measured)
  SpanBuffer* feedback = nullptr;  // the last rendered feedback
  SpanBuffer* popin = nullptr;     // the pop-in buffer: its own divisor, or the feedback itself
};

class ViewStream {
 public:
  // `render_threads`: workers rendering ahead (0: this thread renders in frame()). `block_shift`:
  // spans never cross a 2^block_shift-texel block (the tile size); `keep_samples`: what the first
  // renders keep (a consumer's keep_samples() before its first frame). plan and scene must
  // outlive the stream.
  ViewStream(const ReplayConfig& cfg, const FramePlan& plan, const IScene& scene, int block_shift, bool keep_samples,
             int render_threads);
  ~ViewStream();
  ViewStream(const ViewStream&) = delete;
  ViewStream& operator=(const ViewStream&) = delete;

  // view.render_threads resolved (auto: one per core; the real clock renders in the loop unless
  // asked) and capped so that the ring of buffers fits in memory (RenderAhead::cap_threads).
  static int resolve_threads(const ReplayConfig& cfg, const FramePlan& plan, bool real_clock);
  int render_threads() const { return threads_; }

  // Before frame 0 in the real clock: a renderer's first call sets itself up (~2 MB of scratch
  // touched for the first time: 8 ms of frame 0 on a paravirtualised VM; docs/real-engine.md §7a).
  // Render-ahead waits until each worker has rendered one frame; in the loop, frame 0 is rendered
  // once and thrown away. `keep_samples` as frame 0 will ask.
  void warm_up(bool keep_samples);

  // The view of frame f; frames are taken in order 0, 1, ... `keep_samples`: the consumers will
  // read every sample (shade them in the render, not later from the spans). The buffers stay
  // valid until the next call.
  const FrameView& frame(int f, bool keep_samples);

 private:
  const FramePlan& plan_;
  const IScene& scene_;
  const ViewConfig vc_;
  ViewParams vp_, pp_;
  bool separate_popin_ = false;
  int threads_ = 0;
  SpanBuffer fb_, pb_;
  std::unique_ptr<RenderAhead> ahead_;
  std::size_t next_render_ = 0;  // index into plan_.render_frames
  FrameView view_;
};

// The run's own cost, measured by its driver.
struct RunCost {
  double wall_s = 0.0;       // wall time of the frame loop
  double loop_cpu_s = 0.0;   // CPU time of the loop's thread (render-ahead workers excluded)
  int render_threads = 0;
};

// One streaming system stepped on the view: a StreamingRuntime (stream/runtime/streaming_runtime.h,
// the engine's API) driven frame by frame, with the replay's measurements around it (pop-in
// before and after the runtime's uploads, latency per upload, one metrics row per frame). Both
// clocks run through it, so the runtime an engine calls is the one the replays measure.
class SystemRun {
 public:
  // The system run.system names over the scene's texture, a pipeline on env.executor (null: a
  // simulated executor from the config's device models), the throttle policy throttle.policy
  // (runtime_parts, sim/run/runtime_setup.h). Throws InputError for a config the registries
  // refuse. cfg, plan and env are referenced, not copied: they must outlive the run.
  SystemRun(const ReplayConfig& cfg, const FramePlan& plan, const IScene& scene, const ReplayEnv& env);
  // The same over a texture without a scene (a feedback trace's replay: nothing renders).
  SystemRun(const ReplayConfig& cfg, const FramePlan& plan, TextureExtent texture, const ReplayEnv& env);
  ~SystemRun();
  SystemRun(const SystemRun&) = delete;
  SystemRun& operator=(const SystemRun&) = delete;

  IStreamingSystem& system() { return rt_->system(); }
  const IStreamingSystem& system() const { return rt_->system(); }
  StreamingRuntime& runtime() { return *rt_; }
  // Spans of the view never cross a tile: log2 of the tile size, rounded down.
  int block_shift() const;
  // Whether this system reads every sample of the next frame (not only spans).
  bool keep_samples() const;
  // Whether it may read every sample at some frame of the run (keep_samples now, or a policy that
  // may bias the feedback): consumers on threads of their own have the samples rendered up front.
  bool may_keep_samples() const;

  // Frame f starts at `now`: completions up to it are collected.
  void begin_frame(int f, Ticks now);
  // The rest of frame f on its view (after begin_frame(f, ...)). `share` (optional; its
  // begin_frame called with view.popin): pop-in resolved by another run in the same state this
  // frame is copied from it, and this run's is offered to the next (popin_share.h). The run's
  // results are the same with or without it.
  void step(const FrameView& view, PopinShare* share = nullptr);
  // What this run's steps took from their shares and offered to them.
  const PopinShare::Counts& popin_share_counts() const { return share_counts_; }
  // The summary of the frames stepped so far (docs/metrics.md); moves the metrics out.
  ReplayResult summarize(const RunCost& cost);

 private:
  glm::dvec3 motion(int f, FrameRow& row);
  class Uploads;  // the runtime's upload sink: latency per tile, then ReplayEnv::on_upload
  void on_upload(const TileUpload& u, FrameRow& row);
  // The resident levels of the pop-in spans now, into `own` or from the share's entry of the same
  // state; `marking`: the lookup marks what it samples (applied from the entry on a share).
  const SpanLevels& popin_levels(const SpanBuffer& spans, PopinShare* share, const ResidencyFingerprint* fp, bool marking,
                                 SpanLevels& own);
  // Hands the runtime the feedback of this frame, or with view.feedback_latency = k the one
  // rendered k frames before (none before frame k), as an engine reads its feedback back.
  void set_feedback(const FrameView& view);
  void add_cache_bounds(nlohmann::json& summary) const;

  const ReplayConfig& cfg_;
  const FramePlan& plan_;
  const ReplayEnv& env_;
  std::unique_ptr<AccessLogs> own_accesses_;  // metrics.opt without env.accesses: recorded here
  AccessLogs* accesses_ = nullptr;             // where the levels' accesses go (null: not recorded)
  std::unique_ptr<StreamingRuntime> rt_;
  const SimExecutor* sim_ = nullptr;  // the runtime's executor when simulated
  IStreamingSystem* system_ = nullptr;  // the runtime's
  Pipeline* pipe_ = nullptr;            // the runtime's
  int num_levels_ = 1;

  // Frame state.
  int frame_ = 0;
  Ticks now_ = 0;
  PipelineCounters c0_;
  int clamp_ = 0;
  double bias_ = 0.0;
  bool in_turn_ = false;
  bool cut_ = true;  // the first frame has no predecessor: treat it as a cut
  SpanLevels lv_before_, lv_after_;
  std::vector<std::uint64_t> marks_;  // popin_levels: the marks of a lookup offered to a share
  PopinShare::Counts share_counts_;
  std::uint64_t level_upload_[TileKey::kMaxLevels] = {};
  // view.feedback_latency > 0: copies of the feedback rendered in the last k frames, oldest first
  // (a deque: the runtime holds a reference to the front one until the frame ends).
  struct DelayedFeedback {
    int frame = 0;  // the frame it was rendered at
    SpanBuffer spans;
  };
  std::deque<DelayedFeedback> delayed_;
  ReplayResult res_;
};

}  // namespace vtsim
