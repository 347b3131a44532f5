#include "gl/gl_replay.h"
#include "gl/video_writer.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <thread>
#include <tuple>

#include "core/camera.h"
#include "core/error.h"
#include "core/image_io.h"
#include "core/view.h"
#include "gl/gl_clip.h"
#include "gl/gl_context.h"
#include "gl/gl_renderer.h"
#include "gl/gl_stream.h"
#include "sim/run/provenance.h"
#include "sim/run/real_replay.h"
#include "sim/run/replay.h"
#include "sim/run/resources.h"
#include "sim/run/run_summary.h"
#include "sim/trace/feedback_trace.h"
#include "sim/run/runtime_setup.h"
#include "stream/exec/threaded_executor.h"
#include "stream/system/clipmap_backed.h"

namespace vtsim::gl {

namespace {

// The GPU's sink with the replay's bookkeeping: each tile's latency (docs/metrics.md: first
// needed -> uploaded; the upload stage is the GPU copy, not modelled here: 0) and the row's bytes.
class Sink final : public IUploadSink {
 public:
  Sink(StreamedTexture& vt, MetricsCollector& m, std::vector<std::uint64_t>& level_upload) : vt_(vt), m_(m), level_upload_(level_upload) {}
  void begin(FrameRow& row, int frame, Ticks now) {
    row_ = &row;
    frame_ = frame;
    now_ = now;
  }
  void upload(const TileUpload& t) override {
    const auto c0 = std::chrono::steady_clock::now();
    vt_.upload(t);
    cpu_ms_ += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - c0).count();
    const UploadItem& u = *t.item;
    m_.add_latency(upload_latency(u, now_, frame_, 0));  // the GPU copy is timed by GL queries
    if (u.key.level() < level_upload_.size()) level_upload_[u.key.level()] += u.bytes;
    row_->upload_bytes += u.bytes;
    ++row_->uploads;
  }
  // The submitting thread's wall time in the copies (llvmpipe copies there), ms.
  double cpu_ms() const { return cpu_ms_; }

 private:
  StreamedTexture& vt_;
  MetricsCollector& m_;
  std::vector<std::uint64_t>& level_upload_;
  FrameRow* row_ = nullptr;
  int frame_ = 0;
  Ticks now_ = 0;
  double cpu_ms_ = 0.0;
};

// Every entry of the GPU's page table names a resident page's (slot, level).
bool gl_page_table_consistent(const GlReplayRun& run, const StreamedVt& vt, TextureExtent ext, int tile, int levels) {
  std::map<std::int64_t, int> slot_level;
  for (const auto& [page, slot] : run.page_table) slot_level[slot] = static_cast<int>(page.level());
  bool ok = run.page_table.size() == run.pool_pages.size();
  for (const auto& [page, slot] : run.pool_pages) {
    const auto it = run.page_table.find(page);
    ok = ok && it != run.page_table.end() && it->second == static_cast<std::int64_t>(slot);
  }
  const std::int64_t W = ext.width, H = ext.height;
  for (int l = 0; l < levels && ok; ++l) {
    const std::int64_t tx = (std::max<std::int64_t>(W >> l, 1) + tile - 1) / tile, ty = (std::max<std::int64_t>(H >> l, 1) + tile - 1) / tile;
    for (std::int64_t y = 0; y < ty && ok; ++y)
      for (std::int64_t x = 0; x < tx && ok; ++x) {
        const std::uint32_t e = vt.entry(l, x, y);
        if (e == StreamedVt::kNone) continue;
        const int el = static_cast<int>(e >> 24);
        const auto s = slot_level.find(static_cast<std::int64_t>(e & 0xffffffu));
        ok = el >= l && s != slot_level.end() && s->second == el &&
             run.page_table.count(TileKey(0, static_cast<std::uint32_t>(el), x >> (el - l), y >> (el - l))) == 1;
      }
  }
  return ok;
}

// The GPU's clip stack against the runtime's clipmap: the same windows, and each window tile's
// slot valid on the GPU exactly when the clipmap holds the tile in every layer.
bool gl_clip_consistent(GlReplayRun& run, const StreamedClip& clip, const IStreamingSystem& sys, int layers) {
  run.gpu_windows = clip.gpu_windows();
  sys.clip_windows(run.runtime_windows);
  bool ok = run.gpu_windows == run.runtime_windows;
  const auto* cm = dynamic_cast<const ClipmapBacked*>(&sys);
  if (!cm) return false;
  for (int l = 0; ok && l < clip.levels(); ++l) {
    const ClipWindow& w = run.runtime_windows[static_cast<std::size_t>(l)];
    for (std::int64_t y = w.y0; ok && y < w.y0 + w.h; ++y)
      for (std::int64_t x = w.x0; ok && x < w.x0 + w.w; ++x) {
        bool all = true;
        for (int k = 0; k < layers; ++k) all = all && cm->clipmap().resident(TileKey(static_cast<std::uint32_t>(k), static_cast<std::uint32_t>(l), x, y));
        ok = all == clip.gpu_tile_valid(l, x, y);
      }
  }
  return ok;
}

// The GPU feedback each frame acted on, as a feedback trace (docs/feedback.md): the read-back
// texels that sampled the texture, each at its desired level's tile, counted per tile.
class GpuFeedbackRecorder {
 public:
  GpuFeedbackRecorder(const std::string& path, const vtsim::FeedbackHeader& h) : w_(path, h) {}
  void add(const Pose& pose, bool fresh, const FeedbackFrame& fb, int levels, std::uint32_t tile) {
    frame_.t_s = pose.t_s;
    frame_.has_pose = true;
    frame_.pose = pose;
    // Before the first readback the engine's feedback is empty: the first frame carries that (a
    // trace's first frame is fresh), the next ones reuse it until a readback arrives.
    frame_.fresh = fresh || w_.frames() == 0;
    frame_.measured = true;
    frame_.tiles.clear();
    if (fresh) {
      keys_.clear();
      for (const FeedbackTexel& t : fb.px) {
        if (t.status != 1) continue;
        const int l = desired_level(t.lod, levels);
        keys_.push_back({static_cast<std::uint32_t>(l), 0, static_cast<std::uint64_t>(t.u >> l) / tile,
                         static_cast<std::uint64_t>(t.v >> l) / tile, 1});
      }
      std::sort(keys_.begin(), keys_.end(), [](const vtsim::FeedbackTile& a, const vtsim::FeedbackTile& b) {
        return std::tie(a.layer, a.level, a.x, a.y) < std::tie(b.layer, b.level, b.x, b.y);
      });
      for (const vtsim::FeedbackTile& k : keys_) {
        if (!frame_.tiles.empty() && frame_.tiles.back().level == k.level && frame_.tiles.back().x == k.x && frame_.tiles.back().y == k.y)
          ++frame_.tiles.back().samples;
        else
          frame_.tiles.push_back(k);
      }
    }
    w_.add(frame_);
  }
  std::uint64_t finish() {
    w_.finish();
    return w_.bytes();
  }

 private:
  vtsim::FeedbackWriter w_;
  vtsim::FeedbackFrame frame_;
  std::vector<vtsim::FeedbackTile> keys_;
};

// The summary, in `vtsim replay`'s schema: the measured sections from the builder every runtime
// client shares (sim/run/run_summary.h), then this client's cost and its "gl" section.
void gl_summary(GlReplayRun& run, Context& ctx, const ReplayConfig& bound, const FramePlan& plan, StreamingRuntime& rt,
                const StreamedTexture& vt, const std::vector<std::uint64_t>& level_upload, const FeedbackSettings& fs,
                std::uint64_t feedback_read) {
  nlohmann::json& s = run.result.summary;
  static const std::string kClock = "gl";
  fill_run_summary(s, {bound, plan, kClock, rt.pipeline(), rt.system(), run.result.metrics, level_upload.data(),
                       rt.executor().now(), nullptr});
  const double duration_s = plan.duration_s;
  s["run"] = {{"wall_s", run.seconds},
              {"render_threads", 0},
              {"loop_cpu_s", 0.0},
              {"frames_per_s", run.seconds > 0 ? plan.frames / run.seconds : 0.0},
              {"x_realtime", run.seconds > 0 ? duration_s / run.seconds : 0.0},
              {"peak_rss_MB", peak_rss_MB()}};
  s["gl"] = {{"renderer", ctx.renderer()},
             {"gl_version", ctx.version()},
             {"platform", ctx.platform()},
             {"gl_errors", ctx.errors()},
             {"feedback", {buffer_extent(plan.trace.image_width, fs.divisor), buffer_extent(plan.trace.image_height, fs.divisor)}},
             {"feedback_latency_frames", fs.latency},
             {"feedback_frames_read", feedback_read},
             {"sink_uploads", run.sink_uploads},
             {"gpu_page_copies", run.gpu_copies},
             {"upload_gpu_ms_total", vt.upload_gpu_ms()},
             {"upload_timed_frames", vt.timed_frames()},
             {"upload_cpu_ms_total", run.upload_cpu_ms},
             {"seconds", run.seconds},
             {"frames_per_s", run.seconds > 0 ? plan.frames / run.seconds : 0.0},
             {"page_table_consistent", run.page_table_consistent}};
  if (bound.run.system == "clipmap") {
    s["gl"].erase("page_table_consistent");
    s["gl"]["clip_stack_consistent"] = run.clip_consistent;
  }
}

}  // namespace

GlReplayRun run_gl_replay(Context& ctx, const ReplayConfig& cfg, const Trace& trace, const TileStore& store,
                          const GlReplayOptions& o) {
  ReplayConfig bound = cfg;
  for (const std::string& w : bind_store_texture(bound, store))
    if (o.warn) o.warn(w);
  const bool clipmap = bound.run.system == "clipmap";
  if (bound.run.system != "vt" && !clipmap)
    throw InputError("run.system", fmt::format("gl replay streams the vt and clipmap systems, not '{}'", bound.run.system));
  const int latency = o.latency < 0 ? cfg.view.feedback_latency : o.latency;
  if (latency > 16) throw InputError("--latency", "must be in [0, 16]");
  if (o.png_every < 1) throw InputError("--png-every", "must be >= 1");
  const store::LayerInfo& l0 = store.layer(0);
  if (l0.bits != 8) throw InputError("--store", fmt::format("layer 0 has {}-bit channels; the GL client draws 8-bit ones", l0.bits));
  const FramePlan plan = plan_frames(bound, trace);
  Renderer r(ctx, scene_config_of(bound));
  const TextureExtent ext = r.texture();
  if (ext.width != static_cast<std::int64_t>(store.geometry().width) || ext.height != static_cast<std::int64_t>(store.geometry().height))
    throw InputError("scene", fmt::format("the scene's texture is {}x{} texels, the store's {}x{}", ext.width, ext.height,
                                          store.geometry().width, store.geometry().height));
  auto rt = make_streaming_runtime(bound, store);
  const int tile = bound.texture.tile_size, levels = rt->system().num_levels();
  std::unique_ptr<StreamedTexture> tex;
  StreamedVt* vtp = nullptr;
  StreamedClip* clip = nullptr;
  if (clipmap) {
    ClipGeometry g;
    g.extent = ext;
    g.tile = tile;
    g.border = static_cast<int>(store.geometry().border);
    g.channels = static_cast<int>(l0.channels);
    g.layers = static_cast<int>(store.layer_count());
    g.clipsize = bound.clipmap.clipsize;
    g.filter_margin = bound.clipmap.filter_margin_texels;
    g.invalid_border = bound.clipmap.invalid_border_tiles;
    auto c = std::make_unique<StreamedClip>(r, g);
    if (c->levels() != levels)
      throw std::logic_error(fmt::format("gl clip stack: {} levels where the clipmap has {}", c->levels(), levels));
    clip = c.get();
    tex = std::move(c);
  } else {
    auto v = std::make_unique<StreamedVt>(r, tile, static_cast<int>(store.geometry().border), static_cast<int>(l0.channels),
                                          static_cast<std::int64_t>(bound.vt.pool_pages), levels);
    vtp = v.get();
    tex = std::move(v);
  }
  StreamedTexture& vt = *tex;
  GlReplayRun run;
  MetricsCollector& m = run.result.metrics;
  m.set_system_columns(rt->system().frame_counter_names());
  std::vector<std::uint64_t> level_upload(static_cast<std::size_t>(levels), 0);
  Sink sink(vt, m, level_upload);
  FeedbackSettings fs;
  fs.divisor = bound.view.divisor;
  fs.lod_bias = static_cast<float>(bound.view.lod_bias);
  fs.anisotropic = bound.view.anisotropic;
  fs.max_aniso = static_cast<float>(bound.view.max_aniso);
  fs.near_m = bound.view.near_m;
  fs.far_m = bound.view.far_m;
  fs.latency = latency;
  double feedback_bias = 0.0;
  int clamp = 0;
  std::uint64_t feedback_read = 0;
  FeedbackFrame fb;
  std::unique_ptr<GpuFeedbackRecorder> rec;
  if (!o.record_feedback.empty()) {
    vtsim::FeedbackHeader h;
    h.texture = {bound.texture.width, bound.texture.height};
    h.tile_size = static_cast<std::uint32_t>(tile);
    h.levels = static_cast<std::uint32_t>(levels);
    h.feedback_width = static_cast<std::uint32_t>(buffer_extent(plan.trace.image_width, fs.divisor));
    h.feedback_height = static_cast<std::uint32_t>(buffer_extent(plan.trace.image_height, fs.divisor));
    h.image_width = static_cast<std::uint32_t>(plan.trace.image_width);
    h.image_height = static_cast<std::uint32_t>(plan.trace.image_height);
    h.frame_rate = 1.0 / plan.period_s;
    rec = std::make_unique<GpuFeedbackRecorder>(o.record_feedback, h);
  }
  std::unique_ptr<VideoWriter> video;
  if (!o.video.empty()) video = std::make_unique<VideoWriter>("--video", o.video, plan.trace.image_width, plan.trace.image_height, 1.0 / plan.period_s);
  // An engine builds its pipelines before its first frame: one feedback and one main pass off the
  // clock (llvmpipe compiles a shader's variant at its first draw, ~0.1 s), then the executor's
  // clock restarts at 0, as the real clock's frame loop does at frame 0 (sim/run/real_replay.cpp),
  // so frame 0 starts at its trace time and setup is not counted in the tiles' latency.
  if (plan.frames > 0) {
    const Camera cam0 = make_camera(plan.trace.poses.front(), plan.trace.image_width, plan.trace.image_height);
    (void)r.feedback_now(cam0, fs, 0, 0);
    vt.apply(FrameUpdates{});
    (void)vt.draw(cam0, fs, 0);
  }
  if (auto* te = dynamic_cast<ThreadedExecutor*>(&rt->executor())) te->restart_clock();
  const auto t0 = std::chrono::steady_clock::now();
  for (int f = 0; f < plan.frames; ++f) {
    const Pose& pose = plan.trace.poses[static_cast<std::size_t>(f)];
    if (o.pace)
      while (rt->executor().now() < plan.target(f))
        std::this_thread::sleep_for(std::chrono::microseconds(200));
    const Ticks now = rt->executor().now();
    const PipelineCounters c0 = rt->pipeline().counters();
    rt->begin_frame(now);
    rt->set_camera(pose);
    const Camera cam = make_camera(pose, plan.trace.image_width, plan.trace.image_height);
    FeedbackSettings ffs = fs;
    ffs.lod_bias = fs.lod_bias + static_cast<float>(feedback_bias);
    int ox = 0, oy = 0;
    feedback_tile_offset(o.sampling, f, fs.divisor, ox, oy);
    const bool fresh = r.feedback(cam, ffs, ox, oy, f, fb);
    if (fresh) {
      ++feedback_read;
      for (const FeedbackTexel& t : fb.px) {
        if (t.status != 1) continue;
        const int l = desired_level(t.lod, levels);
        rt->request(TileKey(0, static_cast<std::uint32_t>(l), static_cast<std::int64_t>(t.u >> l) / tile,
                            static_cast<std::int64_t>(t.v >> l) / tile));
      }
    }
    if (rec) rec->add(pose, fresh, fb, levels, static_cast<std::uint32_t>(tile));
    FrameRow row;
    row.frame = f;
    row.t_s = ticks_to_seconds(plan.target(f));
    sink.begin(row, f, now);
    const FrameUpdates& u = rt->end_frame(sink);
    vt.apply(u);
    if (u.throttle_changed) m.add_throttle_change({f, row.t_s, clamp, u.clamp, u.feedback_bias, u.reason});
    clamp = u.clamp;
    feedback_bias = u.feedback_bias;
    const PopinCount pc = vt.draw(cam, fs, u.clamp, u.sample_bias);
    row.clamp = u.clamp;
    row.bias = u.feedback_bias;
    row.measured = true;
    row.samples = static_cast<std::uint32_t>(pc.samples);
    row.blurry = static_cast<std::uint32_t>(pc.blurry);
    row.deficit_sum = static_cast<double>(pc.deficit);
    row.finest_needed = rt->finest_needed();
    row.needs = static_cast<std::uint32_t>(rt->needs());
    row.live_requests = static_cast<std::uint32_t>(rt->pipeline().live_requests());
    const PipelineCounters& c1 = rt->pipeline().counters();
    row.disk_bytes = c1.disk_bytes - c0.disk_bytes;
    row.decoded_bytes = c1.decoded_bytes - c0.decoded_bytes;
    row.ram_bytes = rt->pipeline().ram_bytes_used();
    row.throttled_needs = rt->system().throttled_needs();
    rt->system().frame_counters(row.system);
    m.add_frame(row);
    if (video) {
      int w = 0, h = 0;
      video->add(vt.read_colour(w, h).data());
    }
    if (!o.frames_png.empty() && f % o.png_every == 0) {
      int w = 0, h = 0;
      const std::vector<std::uint8_t> px = vt.read_colour(w, h);
      const std::string path = fmt::format("{}/frame_{:06}.png", o.frames_png, f);
      const auto res = image_io::write_file(path, w, h, 4, image_io::PixelType::u8, px.data(), true);
      if (res.status != image_io::WriteStatus::ok) throw InputError("--frames-png", path + ": " + res.error);
    }
  }
  while (r.drain(fb)) {
  }
  run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (rec) run.feedback_trace_bytes = rec->finish();
  if (video) {
    video->finish();
    run.video_frames = video->frames();
  }
  run.sink_uploads = vt.uploads();
  run.upload_cpu_ms = sink.cpu_ms();
  run.gpu_copies = vt.copies();
  if (vtp) {
    run.page_table = vtp->page_table();
    rt->system().pool_pages(run.pool_pages);
    run.page_table_consistent = gl_page_table_consistent(run, *vtp, ext, tile, levels);
  }
  if (clip) run.clip_consistent = gl_clip_consistent(run, *clip, rt->system(), static_cast<int>(store.layer_count()));

  gl_summary(run, ctx, bound, plan, *rt, vt, level_upload, fs, feedback_read);
  return run;
}

}  // namespace vtsim::gl
