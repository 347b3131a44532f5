#pragma once
// `vtsim gl replay` (docs/gpu.md, "Streaming through the runtime"): the GL client streaming a
// virtual texture or a clipmap through the engine-facing runtime
// (stream/runtime/streaming_runtime.h) in the real clock, one frame per frame of the trace
// resampled to run.fps:
//   begin_frame(now); set_camera; the GPU's feedback pass, read back `latency` frames late, one
//   request(key) per textured feedback sample (repeats weigh more, as the simulator's span
//   buffer does; the clipmap reads its finest level and the tiles' importance); end_frame(the
//   sink: StreamedVt's PBO-ring uploads into the physical page texture, or StreamedClip's into
//   the clip stack, gl_clip.h); apply the page-table or window updates; the main pass sampling
//   the texture, pop-in summed on the GPU.
// Its summary and per-frame CSV have the schema of `vtsim replay` (docs/metrics.md), clock "gl".
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "core/trace.h"
#include "sim/run/frame_loop.h"
#include "sim/run/replay_config.h"
#include "sim/view/gpu_model.h"
#include "stream/store/tile_store.h"

namespace vtsim::gl {

class Context;

struct GlReplayOptions {
  FeedbackSampling sampling = FeedbackSampling::middle;
  int latency = -1;               // feedback read back this many frames late (k); -1: view.feedback_latency
  bool pace = true;               // start frame f no earlier than its trace time (the real clock)
  std::string frames_png;         // non-empty: the main pass of every png_every-th frame, as PNG
  long long png_every = 60;
  // Non-empty: a video of every frame's main pass (ffmpeg, gl/video_writer.h; the container by
  // the extension: .mp4, .mkv, .mov, .webm), written whole at the end or not at all.
  std::string video;
  // Non-empty: the GPU feedback each frame acted on, as a feedback trace (docs/feedback.md): at
  // frame f the tiles of the feedback read back then (rendered `latency` frames before), with the
  // frame's pose; frames with no readback are not fresh. Written whole at the end, or not at all.
  std::string record_feedback;
  std::function<void(const std::string&)> warn;
};

struct GlReplayRun {
  ReplayResult result;
  std::uint64_t sink_uploads = 0;     // tiles the runtime handed to the GPU's sink
  std::uint64_t gpu_copies = 0;       // of those, layer-0 pages copied into the physical texture
  std::map<TileKey, std::int64_t> page_table;                 // the GPU's mirror at the end
  std::vector<std::pair<TileKey, std::uint32_t>> pool_pages;  // the runtime's pool at the end
  bool page_table_consistent = false;  // VT: every page-table entry points at a resident page's slot
  // Clipmap: each level's window as the GPU's shader reads it, and the runtime's (clip_windows)
  // at the end; clip_consistent: they are equal, and every window tile's GPU slot is valid exactly
  // when the clipmap holds that tile in every layer.
  std::vector<ClipWindow> gpu_windows, runtime_windows;
  bool clip_consistent = false;
  double seconds = 0.0;                // wall time of the frame loop
  std::uint64_t feedback_trace_bytes = 0;  // GlReplayOptions::record_feedback's size, bytes
  std::uint64_t video_frames = 0;          // frames in GlReplayOptions::video
  double upload_cpu_ms = 0.0;              // the submitting thread's wall time in the sink's copies (gl.upload_cpu_ms_total)
};

// Throws InputError for a config the store does not match (before the first frame), a system
// other than vt and clipmap, or a scene whose texture differs from the store's.
GlReplayRun run_gl_replay(Context& ctx, const ReplayConfig& cfg, const Trace& trace, const TileStore& store,
                          const GlReplayOptions& options = {});

}  // namespace vtsim::gl
