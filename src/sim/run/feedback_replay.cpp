#include "sim/run/feedback_replay.h"

#include <sys/resource.h>
#include <time.h>

#include <bit>
#include <chrono>
#include <filesystem>

#include <fmt/format.h>

#include "core/error.h"
#include "sim/run/systems.h"
#include "stream/system/i_system.h"
#include "stream/system/vt_system.h"

namespace vtsim {

namespace {

// What a feedback trace cannot give: the samples inside a tile (their LODs and texels). A run
// that asks for them (a feedback or sampling bias moves levels inside a tile) is refused.
class NoSamples final : public ISampleSource {
 public:
  explicit NoSamples(std::string path) : path_(std::move(path)) {}
  void render_pixels(const SpanBuffer&, std::uint32_t, std::uint32_t, std::vector<ViewSample>&) const override {
    throw InputError(path_, "this run needs per-sample LODs (a feedback or sampling bias moves levels inside a tile): a "
                            "feedback trace holds tiles and sample counts only (docs/feedback.md)");
  }

 private:
  std::string path_;
};

double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// A frame's tiles as spans: one single-texel span per layer-0 tile at the tile's first texel.
void tiles_to_spans(const FeedbackHeader& h, const std::vector<FeedbackTile>& tiles, SpanBuffer& sb) {
  sb.spans.clear();
  sb.samples = 0;
  std::uint32_t pixel = 0;
  for (const FeedbackTile& t : tiles) {
    if (t.layer != 0) continue;  // a page's request holds every layer (docs/feedback.md)
    ViewSpan s;
    s.u_lo = s.u_hi = static_cast<std::int64_t>(t.x * h.tile_size) << t.level;
    s.v_lo = s.v_hi = static_cast<std::int64_t>(t.y * h.tile_size) << t.level;
    s.pixel = s.first = pixel;
    s.count = t.samples;
    s.level = static_cast<std::int32_t>(t.level);
    pixel += t.samples;
    sb.samples += t.samples;
    sb.spans.push_back(s);
  }
}

}  // namespace

FeedbackRecorder::FeedbackRecorder(std::string path, const ReplayConfig& cfg)
    : path_(std::move(path)),
      texture_{cfg.texture.width, cfg.texture.height},
      tile_size_(static_cast<std::uint32_t>(cfg.texture.tile_size)) {}

void FeedbackRecorder::operator()(const FramePlan& plan, const FrameView& view) {
  if (!w_) {
    FeedbackHeader h;
    h.texture = texture_;
    h.tile_size = tile_size_;
    h.levels = static_cast<std::uint32_t>(view.feedback->levels);
    h.layers = 1;
    h.feedback_width = static_cast<std::uint32_t>(view.feedback->width);
    h.feedback_height = static_cast<std::uint32_t>(view.feedback->height);
    h.image_width = static_cast<std::uint32_t>(plan.trace.image_width);
    h.image_height = static_cast<std::uint32_t>(plan.trace.image_height);
    h.frame_rate = 1.0 / plan.period_s;
    w_ = std::make_unique<FeedbackWriter>(path_, h);
  }
  frame_.t_s = view.pose->t_s;
  frame_.has_pose = true;
  frame_.pose = *view.pose;
  frame_.fresh = view.fresh;
  frame_.measured = view.measured;
  if (view.fresh) feedback_tiles(*view.feedback, tile_size_, frame_.tiles);
  else frame_.tiles.clear();
  w_->add(frame_);
}

std::uint64_t FeedbackRecorder::finish() {
  if (!w_) throw InputError(path_, "no frame was recorded");
  w_->finish();
  return w_->bytes();
}

ReplayResult run_feedback_replay(const ReplayConfig& cfg, const std::string& path, const ReplayEnv& env) {
  const auto wall0 = std::chrono::steady_clock::now();
  const double cpu0 = thread_cpu_s();
  // Pass 1: the frames' times, poses and flags (the plan); the tiles are read again in pass 2,
  // block by block, so a long trace is never held whole.
  FeedbackReader pass1(path);
  const FeedbackHeader h = pass1.header();
  if (!streaming_systems().at(cfg.run.system).caps.page_pool)
    throw InputError("--feedback", fmt::format("run.system '{}': feedback replays drive a virtual texture ({}) only", cfg.run.system,
                                               VtSystem::kName));
  if (cfg.view.popin_divisor > 0 && cfg.view.popin_divisor != cfg.view.divisor)
    throw InputError("--feedback", fmt::format("view.popin_divisor = {}: a feedback replay measures pop-in on the trace's tiles "
                                               "(its feedback resolution); set view.popin_divisor = 0", cfg.view.popin_divisor));
  if (h.texture.width != cfg.texture.width || h.texture.height != cfg.texture.height)
    throw InputError(path + ":header", fmt::format("field 'texture': {}x{} texels, the config's texture is {}x{}", h.texture.width,
                                                   h.texture.height, cfg.texture.width, cfg.texture.height));
  if (static_cast<int>(h.tile_size) != cfg.texture.tile_size)
    throw InputError(path + ":header", fmt::format("field 'tile_size': {} texels, the config's texture.tile_size is {}", h.tile_size,
                                                   cfg.texture.tile_size));
  if (!std::has_single_bit(h.tile_size))
    throw InputError(path + ":header", fmt::format("field 'tile_size': {} is not a power of two: pages then split feedback "
                                                   "spans, which needs per-sample texels", h.tile_size));
  FramePlan plan;
  plan.trace.name = std::filesystem::path(path).stem().string();
  plan.trace.source_path = path;
  plan.trace.image_width = static_cast<int>(h.image_width);
  plan.trace.image_height = static_cast<int>(h.image_height);
  std::vector<std::uint8_t> measured;
  {
    FeedbackFrame f;
    while (pass1.next(f)) {
      if (f.fresh) plan.render_frames.push_back(static_cast<int>(plan.trace.poses.size()));
      measured.push_back(f.measured);
      plan.trace.poses.push_back(f.pose);
      if (plan.trace.poses.size() > 100'000'000) throw InputError(path, "more than 10^8 frames");
    }
  }
  if (plan.trace.poses.empty()) throw InputError(path, "the feedback trace has no frames");
  plan.input_poses = plan.trace.poses.size();
  plan.frames = static_cast<int>(plan.trace.poses.size());
  plan.t0_s = plan.trace.poses.front().t_s;
  plan.input_duration_s = plan.trace.poses.back().t_s - plan.t0_s;
  plan.period_s = 1.0 / h.frame_rate;
  plan.duration_s = plan.input_duration_s + plan.period_s;
  plan.feedback_every = cfg.view.feedback_every;

  SystemRun run(cfg, plan, h.texture, env);
  if (run.may_keep_samples())
    throw InputError("--feedback", fmt::format("throttle.policy '{}' may bias the feedback, which needs per-sample LODs: a "
                                               "feedback trace holds tiles and sample counts only (docs/feedback.md)",
                                               cfg.throttle.policy));
  const NoSamples no_samples(path);
  SpanBuffer sb;
  sb.block_shift = run.block_shift();
  sb.keep_samples = false;
  sb.width = static_cast<int>(h.feedback_width);
  sb.height = static_cast<int>(h.feedback_height);
  sb.levels = static_cast<int>(h.levels);
  sb.scene = &no_samples;
  FeedbackReader pass2(path);
  FeedbackFrame f;
  FrameView view;
  view.feedback = view.popin = &sb;
  auto last_progress = wall0;
  for (int i = 0; i < plan.frames; ++i) {
    if (!pass2.next(f)) throw InputError(path, "the file changed while it was read");
    view.frame = i;
    view.pose = &plan.trace.poses[static_cast<std::size_t>(i)];
    view.fresh = f.fresh;
    view.measured = measured[static_cast<std::size_t>(i)] != 0;
    if (f.fresh) tiles_to_spans(h, f.tiles, sb);
    const Ticks target = plan.target(i);
    run.begin_frame(i, env.pace ? env.pace(i, target) : target);
    if (run.keep_samples()) throw InputError("--feedback", "this run needs per-sample LODs (docs/feedback.md)");
    run.step(view);
    if (env.progress) {
      const auto t = std::chrono::steady_clock::now();
      if (t - last_progress > std::chrono::seconds(1)) {
        env.progress(i, plan.frames);
        last_progress = t;
      }
    }
  }
  RunCost cost;
  cost.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  cost.loop_cpu_s = thread_cpu_s() - cpu0;
  cost.render_threads = 0;
  ReplayResult r = run.summarize(cost);
  r.summary["trace"]["feedback"] = {{"path", path},
                                    {"feedback_size", {h.feedback_width, h.feedback_height}},
                                    {"levels", h.levels},
                                    {"frame_rate", h.frame_rate}};
  return r;
}

}  // namespace vtsim
