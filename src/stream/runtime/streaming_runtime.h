#pragma once
// The streaming runtime an engine calls each frame (docs/embedding.md, "Streaming from an
// engine"): one streaming system (clipmap, virtual texture or terrain) with its request pipeline, throttle
// policy and upload budget, stepped by the caller's frames. Both clocks' replays are clients of it
// (sim/run/frame_loop.h's SystemRun drives one per run), so an engine streams through the same path
// the simulator measures.
//
// A frame, on the engine's render thread:
//   rt.begin_frame(now);                      // completions of the IO and decode pools up to now
//   rt.set_camera(pose, velocity, cut);       // where the camera is (the clipmap's windows follow it)
//   rt.request(key) ... / rt.set_feedback(spans);  // what the feedback pass saw
//   const FrameUpdates& u = rt.end_frame(sink);    // sink.upload(...) per tile, then the updates
// then the engine applies u.page_table (VT) or u.windows (clipmap) and u.clamp / u.sample_bias
// (MaxTextureLOD / LOD bias) before it draws.
//
// Threading contract (the runtime is not thread-safe; one thread, the engine's render thread,
// calls every member, like folly's EvictingCacheMap):
//   - begin_frame, set_camera, request, set_feedback, end_frame (or plan_uploads +
//     commit_uploads), and every accessor: the calling thread only, in that order each frame.
//   - IUploadSink::upload runs on the calling thread, inside end_frame / commit_uploads, once per
//     tile, before the tile is committed: the engine copies the bytes (a GPU copy, glTexSubImage2D
//     from a staging buffer) there. It may throw: the tile and every tile after it this frame go
//     back to the upload queue (nothing is lost; they are offered again on a later frame while
//     still wanted), and end_frame throws RuntimeCallError naming the call and the tile.
//   - The executor's pools (stream/exec/threaded_executor.h: io.threads IO threads reading the
//     store, decode.workers decode threads; the simulated executor has none) run reads and
//     decodes between frames; their results are collected in begin_frame and never block it.
//     A TileUpload's bytes (TileData) are immutable and shared: valid for as long as the engine
//     keeps the item's shared_ptr, at least until upload returns.
// Invalidation: the FrameUpdates reference and the planned uploads stay valid until the next
// begin_frame; a SpanBuffer given to set_feedback must outlive end_frame.
//
// Complexity per frame: begin_frame O(C) for C completions; request O(1); end_frame the system's
// step (VT: O(S + W log W) for S feedback samples and W wanted pages; clipmap: O(window tiles
// that changed)) plus the pipeline's O(R + N log N) for R live requests and N needs, plus O(U) for
// U uploads. Nothing else grows with the resident pages.
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "core/tile_data.h"
#include "core/tile_key.h"
#include "core/time.h"
#include "core/trace.h"
#include "core/view_spans.h"
#include "stream/exec/i_executor.h"
#include "stream/exec/pipeline.h"
#include "stream/system/i_system.h"
#include "stream/throttle/i_throttle.h"

namespace vtsim {

// A call the runtime refuses: what() is "StreamingRuntime::<call>: <why>"; call() names the call.
class RuntimeCallError : public std::runtime_error {
 public:
  RuntimeCallError(std::string call, const std::string& why)
      : std::runtime_error("StreamingRuntime::" + call + ": " + why), call_(std::move(call)) {}
  const std::string& call() const { return call_; }

 private:
  std::string call_;
};

// One tile to copy into the GPU's texture.
struct TileUpload {
  TileKey key;
  // Virtual texturing: the physical pool slot (every layer of a page shares it). -1: the key
  // places the tile (clipmap: toroidal slot (x mod w, y mod h) of its level's window, ClipWindow).
  std::int64_t slot = -1;
  const TileData* data = nullptr;  // decoded texels; null in the simulated clock
  const UploadItem* item = nullptr;  // its history (needed when, queue, IO and decode times)
};

// The engine's side of the upload: its GPU copy.
class IUploadSink {
 public:
  virtual ~IUploadSink() = default;
  virtual void upload(const TileUpload& u) = 0;
};

// What the engine applies after a frame's uploads.
struct FrameUpdates {
  int frame = 0;
  // MaxTextureLOD: the finest level the screen may sample (0: unthrottled); the LOD bias the
  // screen samples with; the feedback bias the next feedback pass should apply (VT requests).
  int clamp = 0;
  double sample_bias = 0.0;
  double feedback_bias = 0.0;
  bool throttle_changed = false;  // clamp or bias differ from the previous frame's
  std::string reason;             // the policy's why, when changed
  std::uint32_t uploads = 0;      // tiles handed to the sink and committed
  std::uint64_t upload_bytes = 0;
  std::uint32_t stale = 0;        // uploads no longer wanted (dropped, not handed to the sink)
  std::vector<Ticks> stale_needed;  // when each stale upload was first needed (latency censoring)
  std::vector<PageTableUpdate> page_table;  // VT: this frame's page-table changes, in order
  struct Window {
    int level = 0;
    ClipWindow window;
  };
  std::vector<Window> windows;  // clipmap: levels whose window moved this frame (all at frame 0)
};

// What a runtime runs, built by the caller (sim/run/runtime_setup.h builds it from a replay
// config: make_streaming_runtime for an engine with a store, SystemRun for the replays).
struct RuntimeParts {
  std::unique_ptr<IStreamingSystem> system;
  std::unique_ptr<IThrottlePolicy> throttle;
  IExecutor* executor = nullptr;             // where IO and decode run (not owned unless below)
  std::unique_ptr<IExecutor> owned_executor; // set: executor points at it, and the runtime owns it
  PipelineConfig pipeline;
  TileSizer sizer;
  UploadBudget budget;                       // per frame
  double frame_period_s = 1.0 / 60.0;        // the throttle's deadline
  double service_Bps = 0.0;                  // what the pipeline can bring per second (0: unlimited)
  TextureExtent extent{1, 1};                // level-0 texels (request keys are checked against it)
  int tile_size = 128;                       // texels a side of a tile / page
  int layers = 1;
};

class StreamingRuntime {
 public:
  // Throws std::invalid_argument when a part is missing.
  explicit StreamingRuntime(RuntimeParts parts);
  ~StreamingRuntime();
  StreamingRuntime(const StreamingRuntime&) = delete;
  StreamingRuntime& operator=(const StreamingRuntime&) = delete;

  // Frame f (0, 1, ...) starts at `now` (ticks of the executor's clock, non-decreasing): the
  // executor's completions up to now are collected. Throws RuntimeCallError when a frame is begun
  // and not ended.
  void begin_frame(Ticks now);
  // The camera this frame (the clipmap centres its windows under it; look-ahead prefetch follows
  // the velocity). `cut`: a discontinuity (teleport), the throttle starts over. Optional for VT.
  void set_camera(const Pose& pose, const glm::dvec3& velocity_mps = glm::dvec3(0.0), bool cut = false);
  // One feedback sample asking for tile (key.level(), key.x(), key.y()) (tile coordinates of that
  // level; every layer is streamed, key.layer() must be a layer of the texture). Repeats weigh
  // more (VT priority is by samples). Throws RuntimeCallError for a key outside the texture.
  void request(TileKey key);
  // The feedback as a span buffer (vtsim's renderer, sim/view): `fresh` false reuses the previous
  // buffer's finest level (feedback not rendered this frame). Throws RuntimeCallError when the
  // frame has requests, or when the buffer has neither its samples nor its scene.
  void set_feedback(SpanBuffer& spans, bool fresh = true);
  // The rest of the frame: plan_uploads then commit_uploads.
  const FrameUpdates& end_frame(IUploadSink& sink);

  // end_frame in two steps, for a client that measures between them (the replays' pop-in).
  // plan_uploads: the system, the throttle, needs, dispatch, the uploads chosen within the budget.
  void plan_uploads();
  const std::vector<UploadItem>& planned_uploads() const { return uploads_; }
  const FrameUpdates& commit_uploads(IUploadSink& sink);

  IStreamingSystem& system() { return *sys_; }
  const IStreamingSystem& system() const { return *sys_; }
  Pipeline& pipeline() { return *pipe_; }
  const Pipeline& pipeline() const { return *pipe_; }
  IExecutor& executor() { return *exec_; }
  const IThrottlePolicy& throttle() const { return *parts_.throttle; }
  int frame() const { return frame_; }
  Ticks now() const { return now_; }
  // Needs of the last plan_uploads (tiles wanted and not resident).
  std::size_t needs() const { return needs_.size(); }
  int finest_needed() const { return finest_needed_; }
  const UploadBudget& budget() const { return budget_; }
  double service_Bps() const { return service_; }
  const FrameUpdates& updates() const { return updates_; }

 private:
  enum class Phase : std::uint8_t { idle, begun, planned };
  void require(Phase p, const char* call) const;
  SpanBuffer& request_buffer();

  RuntimeParts parts_;
  IStreamingSystem* sys_ = nullptr;
  IExecutor* exec_ = nullptr;
  std::unique_ptr<Pipeline> pipe_;
  UploadBudget budget_;
  double service_ = 0.0;
  int num_levels_ = 1;
  std::vector<std::int64_t> tiles_x_, tiles_y_;  // tiles a side per level (request checks)

  Phase phase_ = Phase::idle;
  int frame_ = -1;
  Ticks now_ = 0;
  const Pose* pose_ = nullptr;
  Pose own_pose_;
  glm::dvec3 velocity_{0.0};
  bool cut_ = false;
  SpanBuffer* spans_ = nullptr;
  SpanBuffer requests_;  // request()'s samples as a buffer
  bool have_requests_ = false;
  int finest_needed_ = 0;
  int clamp_ = 0;
  double bias_ = 0.0, sample_bias_ = 0.0;
  std::vector<std::uint64_t> missing_;
  std::vector<Need> needs_;
  std::vector<UploadItem> uploads_;
  std::vector<PageTableUpdate> pt_log_;
  std::vector<ClipWindow> windows_, last_windows_;
  FrameUpdates updates_;
};

}  // namespace vtsim
