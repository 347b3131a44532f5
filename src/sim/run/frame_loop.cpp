#include "sim/run/frame_loop.h"

#include <sys/resource.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>

#include "core/camera.h"
#include "core/error.h"
#include "sim/run/cache_bounds.h"
#include "sim/run/provenance.h"
#include "sim/run/render_ahead.h"
#include "sim/run/resources.h"
#include "sim/view/gpu_model.h"
#include "sim/run/run_summary.h"
#include "sim/run/runtime_setup.h"
#include "sim/run/systems.h"
#include "sim/run/timeline.h"
#include "sim/trace/trace_resample.h"
#include "sim/view/scene.h"
#include "stream/exec/sim_executor.h"
#include "stream/system/i_system.h"
#include "stream/system/vt_system.h"
#include "stream/throttle/i_throttle.h"

namespace vtsim {

namespace {

// Angle between two orientations, radians (shortest arc).
double rotation_angle(const glm::dquat& a, const glm::dquat& b) {
  const double d = std::min(1.0, std::fabs(glm::dot(a, b)));
  return 2.0 * std::acos(d);
}

bool same_view(const Pose& a, const Pose& b) {
  return a.pos_m == b.pos_m && a.q.w == b.q.w && a.q.x == b.q.x && a.q.y == b.q.y && a.q.z == b.q.z &&
         a.vfov_deg == b.vfov_deg;
}

ViewParams popin_params(const ReplayConfig& cfg) {
  ViewParams pp = view_params(cfg.view);
  if (cfg.view.popin_divisor > 0) pp.divisor = cfg.view.popin_divisor;
  return pp;
}

bool separate_popin(const ReplayConfig& cfg) {
  return cfg.view.popin_divisor > 0 && cfg.view.popin_divisor != cfg.view.divisor;
}

}  // namespace

ViewParams feedback_params(const ViewConfig& v, int frame) {
  ViewParams p = view_params(v);
  if (v.feedback_sampling == "sequence") feedback_tile_offset(FeedbackSampling::sequence, frame, v.divisor, p.sample_ox, p.sample_oy);
  return p;
}

FramePlan plan_frames(const ReplayConfig& cfg, const Trace& trace_in) {
  if (trace_in.poses.empty()) throw InputError(trace_in.name, "the trace has no poses");
  FramePlan p;
  p.trace = cfg.run.fps > 0 ? resample(trace_in, cfg.run.fps) : trace_in;
  p.input_poses = trace_in.poses.size();
  p.input_duration_s = trace_in.poses.back().t_s - trace_in.poses.front().t_s;
  p.frames = static_cast<int>(p.trace.poses.size());
  if (p.frames == 0) throw InputError(trace_in.name, "the trace has no poses");
  const auto& poses = p.trace.poses;
  p.t0_s = poses.front().t_s;
  p.period_s = cfg.run.fps > 0 ? 1.0 / cfg.run.fps
                               : (p.frames > 1 ? (poses.back().t_s - p.t0_s) / (p.frames - 1) : 1.0 / 60.0);
  p.duration_s = (poses.back().t_s - p.t0_s) + p.period_s;
  p.feedback_every = cfg.view.feedback_every;
  const Pose* last = nullptr;
  // A sequence samples another pixel of each feedback tile every frame: a still pose renders anew.
  const bool per_frame = cfg.view.feedback_sampling == "sequence";
  for (int f = 0; f < p.frames; f += p.feedback_every) {
    const Pose& pose = poses[static_cast<std::size_t>(f)];
    if (last && !per_frame && same_view(pose, *last)) continue;
    p.render_frames.push_back(f);
    last = &pose;
  }
  return p;
}

// ---- ViewStream ----

ViewStream::ViewStream(const ReplayConfig& cfg, const FramePlan& plan, const IScene& scene, int block_shift,
                       bool keep_samples, int render_threads)
    : plan_(plan), scene_(scene), vc_(cfg.view), vp_(view_params(cfg.view)), pp_(popin_params(cfg)),
      separate_popin_(separate_popin(cfg)), threads_(render_threads) {
  fb_.block_shift = pb_.block_shift = block_shift;
  fb_.keep_samples = pb_.keep_samples = keep_samples;
  if (threads_ > 0 && !plan_.render_frames.empty()) {
    const auto camera_of = [&plan](std::size_t j) {
      return make_camera(plan.trace.poses[static_cast<std::size_t>(plan.render_frames[j])], plan.trace.image_width,
                         plan.trace.image_height);
    };
    std::function<ViewParams(std::size_t)> feedback_of;
    if (vc_.feedback_sampling != "middle")
      feedback_of = [this](std::size_t j) { return feedback_params(vc_, plan_.render_frames[j]); };
    ahead_ = std::make_unique<RenderAhead>(scene_, plan_.render_frames.size(), camera_of, vp_,
                                           separate_popin_ ? &pp_ : nullptr, block_shift, keep_samples, threads_,
                                           feedback_of);
  }
  view_.feedback = &fb_;
  view_.popin = separate_popin_ ? &pb_ : &fb_;
}

ViewStream::~ViewStream() = default;

int ViewStream::resolve_threads(const ReplayConfig& cfg, const FramePlan& plan, bool real_clock) {
  // The real clock's cores belong to its IO and decode threads unless the config asks.
  const int wanted = real_clock && cfg.view.render_threads < 0 ? 0 : RenderAhead::resolve_threads(cfg.view.render_threads);
  const ViewParams pp = popin_params(cfg);
  return RenderAhead::cap_threads(wanted, RenderAhead::slot_bytes(plan.trace.image_width, plan.trace.image_height,
                                                                  view_params(cfg.view), separate_popin(cfg) ? &pp : nullptr));
}

void ViewStream::warm_up(bool keep_samples) {
  if (plan_.render_frames.empty()) return;
  if (ahead_) {
    ahead_->wait_rendered(static_cast<std::size_t>(threads_));
    return;
  }
  const Camera cam = make_camera(plan_.trace.poses[static_cast<std::size_t>(plan_.render_frames[0])],
                                 plan_.trace.image_width, plan_.trace.image_height);
  fb_.keep_samples = pb_.keep_samples = keep_samples;
  scene_.render_spans(cam, feedback_params(vc_, plan_.render_frames[0]), fb_);
  if (separate_popin_) scene_.render_spans(cam, pp_, pb_);
}

const FrameView& ViewStream::frame(int f, bool keep_samples) {
  view_.frame = f;
  view_.pose = &plan_.trace.poses[static_cast<std::size_t>(f)];
  view_.measured = plan_.measured(f);
  view_.fresh = next_render_ < plan_.render_frames.size() && plan_.render_frames[next_render_] == f;
  if (!view_.fresh) return view_;  // the last rendered buffers stand in
  // Shade samples in the render (not afterwards, from the spans) while a consumer reads them.
  if (keep_samples != fb_.keep_samples) {
    fb_.keep_samples = pb_.keep_samples = keep_samples;
    if (ahead_) ahead_->set_keep_samples(keep_samples);
  }
  if (ahead_) {
    RenderAhead::Buffers& b = ahead_->next();
    view_.feedback = &b.feedback;
    view_.popin = separate_popin_ ? &b.popin : &b.feedback;
  } else {
    const Camera cam = make_camera(*view_.pose, plan_.trace.image_width, plan_.trace.image_height);
    scene_.render_spans(cam, vc_.feedback_sampling == "middle" ? vp_ : feedback_params(vc_, f), fb_);
    if (separate_popin_) scene_.render_spans(cam, pp_, pb_);
  }
  ++next_render_;
  return view_;
}

// ---- SystemRun ----

SystemRun::SystemRun(const ReplayConfig& cfg, const FramePlan& plan, const IScene& scene, const ReplayEnv& env)
    : SystemRun(cfg, plan, scene.texture(), env) {}

SystemRun::SystemRun(const ReplayConfig& cfg, const FramePlan& plan, TextureExtent texture, const ReplayEnv& env)
    : cfg_(cfg), plan_(plan), env_(env) {
  RuntimeParts parts = runtime_parts(cfg, texture, plan.period_s, env.executor, env.sizer);
  sim_ = dynamic_cast<const SimExecutor*>(parts.owned_executor.get());
  rt_ = std::make_unique<StreamingRuntime>(std::move(parts));
  system_ = &rt_->system();
  pipe_ = &rt_->pipeline();
  num_levels_ = system_->num_levels();
  accesses_ = env.accesses;
  if (!accesses_ && cfg.metrics.opt) {
    own_accesses_ = std::make_unique<AccessLogs>();
    accesses_ = own_accesses_.get();
  }
  if (accesses_) {
    pipe_->record_ram_accesses(&accesses_->ram);
    system_->record_pool_accesses(&accesses_->pool);
  }
  if (env.timeline) {
    pipe_->set_observer(env.timeline);
    system_->record_vram_evictions(env.timeline->eviction_log());
    env.timeline->begin_run(plan.period_s, env.clock_name, plan.trace.name);
  }
  res_.metrics.set_system_columns(system_->frame_counter_names());
  res_.metrics.set_warmup_s(cfg.metrics.warmup_s);
  if (env_.on_start) env_.on_start(*system_);
}

SystemRun::~SystemRun() = default;

// metrics.opt: each level's recorded accesses replayed offline (cache_bounds.h) at the run's
// capacity. The pool's capacity is its slots less the locked pages, whose accesses always hit.
void SystemRun::add_cache_bounds(nlohmann::json& s) const {
  LevelBoundsInput ram;
  ram.policy = cfg_.ram.policy;
  ram.capacity = static_cast<std::uint64_t>(cfg_.ram.capacity_MiB * 1048576.0);
  s["cache"]["ram_bounds"] = level_bounds(accesses_->ram, ram);
  nlohmann::json& sys = s[cfg_.run.system];
  if (sys.contains("pool") && sys.contains("lock_from_level") && sys.contains("locked_pages")) {
    LevelBoundsInput pool;
    pool.policy = cfg_.vt.pool_policy;
    pool.pages = true;
    pool.locked_from_level = sys["lock_from_level"].get<int>();
    const auto locked = sys["locked_pages"].get<std::uint64_t>();
    pool.capacity = VtSystem::unlocked_slots(cfg_.vt.pool_pages, locked);
    sys["pool"]["bounds"] = level_bounds(accesses_->pool, pool);
  }
}

int SystemRun::block_shift() const { return std::bit_width(static_cast<unsigned>(cfg_.texture.tile_size)) - 1; }

bool SystemRun::keep_samples() const { return !system_->uses_spans() || system_->wants_samples(); }

bool SystemRun::may_keep_samples() const { return keep_samples() || rt_->throttle().may_bias(); }

void SystemRun::begin_frame(int f, Ticks now) {
  frame_ = f;
  now_ = now;
  c0_ = pipe_->counters();
  if (env_.timeline) env_.timeline->begin_frame(f, now);
  rt_->begin_frame(now);
  if (rt_->frame() != f) throw std::logic_error("SystemRun::begin_frame: frames out of order");
}

// Cuts, fast turns and the velocity (for look-ahead) between the previous pose and this one.
glm::dvec3 SystemRun::motion(int f, FrameRow& row) {
  glm::dvec3 vel(0.0);
  if (f == 0) return vel;
  const Pose& pose = plan_.trace.poses[static_cast<std::size_t>(f)];
  const Pose& prev = plan_.trace.poses[static_cast<std::size_t>(f - 1)];
  const double dt = pose.t_s - prev.t_s;
  const glm::dvec3 d = pose.pos_m - prev.pos_m;
  cut_ = glm::length(d) > cfg_.metrics.cut_m;
  const double ang = dt > 0 ? rotation_angle(prev.q, pose.q) / dt * 180.0 / 3.14159265358979323846 : 0.0;
  const bool turn = ang > cfg_.metrics.turn_deg_per_s;
  row.event = cut_ || (turn && !in_turn_);
  in_turn_ = turn;
  if (!cut_ && dt > 0) vel = d / dt;
  return vel;
}

// The runtime's upload sink: each tile the system accepted, with its slot.
class SystemRun::Uploads final : public IUploadSink {
 public:
  Uploads(SystemRun& run, FrameRow& row) : run_(run), row_(row) {}
  void upload(const TileUpload& u) override { run_.on_upload(u, row_); }

 private:
  SystemRun& run_;
  FrameRow& row_;
};

// An upload the system accepts: its latency is recorded, then the environment copies it.
void SystemRun::on_upload(const TileUpload& t, FrameRow& row) {
  const UploadItem& u = *t.item;
  const TileLatency lat = upload_latency(u, now_, frame_, upload_ticks(cfg_.upload, u.bytes));
  res_.metrics.add_latency(lat);
  level_upload_[u.key.level()] += u.bytes;
  row.upload_bytes += u.bytes;
  ++row.uploads;
  if (env_.timeline) env_.timeline->on_upload(u, frame_, now_, lat.upload, true);
  if (env_.on_upload) env_.on_upload(u, t.slot);
}

const SpanLevels& SystemRun::popin_levels(const SpanBuffer& spans, PopinShare* share, const ResidencyFingerprint* fp,
                                          bool marking, SpanLevels& own) {
  if (!share || !fp) {
    resident_levels(spans, *system_, own);
    return own;
  }
  if (const PopinShare::Levels* e = share->find(*fp, marking)) {
    if (marking) system_->apply_marks(e->marks);
    ++share_counts_.levels_shared;
    return e->levels;
  }
  ++share_counts_.levels_resolved;
  marks_.clear();
  struct Recording {  // stops recording however the lookup ends
    const IStreamingSystem& s;
    ~Recording() { s.record_marks(nullptr); }
  } rec{*system_};
  if (marking) system_->record_marks(&marks_);
  resident_levels(spans, *system_, own);
  share->publish(*fp, marking, own, marks_);
  return own;
}

void SystemRun::set_feedback(const FrameView& view) {
  const int k = cfg_.view.feedback_latency;
  if (k == 0) {
    rt_->set_feedback(*view.feedback, view.fresh);
    return;
  }
  if (view.fresh) delayed_.push_back({view.frame, *view.feedback});
  // The newest buffer rendered at or before frame − k; older ones are no longer read.
  const int due = view.frame - k;
  while (delayed_.size() >= 2 && delayed_[1].frame <= due) delayed_.pop_front();
  if (delayed_.empty() || delayed_.front().frame > due) return;  // nothing read back yet: no requests
  // Not fresh when the runtime read the same buffer last frame (feedback_every, a still pose).
  rt_->set_feedback(delayed_.front().spans, delayed_.front().frame == due);
}

void SystemRun::step(const FrameView& view, PopinShare* share) {
  set_feedback(view);
  FrameRow row;
  row.frame = frame_;
  row.t_s = view.pose->t_s - plan_.t0_s;
  const glm::dvec3 velocity = motion(frame_, row);
  rt_->set_camera(*view.pose, velocity, cut_);
  // The system, the throttle, needs, dispatch, the uploads within the budget.
  rt_->plan_uploads();
  const FrameUpdates& fu = rt_->updates();
  if (fu.throttle_changed) res_.metrics.add_throttle_change({frame_, row.t_s, clamp_, fu.clamp, fu.feedback_bias, fu.reason});
  clamp_ = fu.clamp;
  bias_ = fu.feedback_bias;
  const std::vector<UploadItem>& uploads = rt_->planned_uploads();
  // Pop-in is measured on what the screen samples before and after this frame's commits.
  // With a share, runs in the same state (equal fingerprints) resolve the spans once.
  const SpanBuffer& mb = *view.popin;
  if (share && share->spans() != &mb) throw std::logic_error("SystemRun::step: the pop-in share is not on this frame's spans");
  const bool has_before = view.measured && !uploads.empty();
  ResidencyFingerprint fp_before, fp_after;
  const bool shared_before = share && has_before && system_->fingerprint(fp_before);
  const SpanLevels* before = nullptr;
  if (has_before) {
    system_->set_mark_sampled(false);
    before = &popin_levels(mb, share, shared_before ? &fp_before : nullptr, false, lv_before_);
  }
  Uploads sink(*this, row);
  for (const Ticks needed : rt_->commit_uploads(sink).stale_needed)
    res_.metrics.add_unserved({needed, now_, Unserved::stale});  // uploaded, but no longer wanted there
  if (view.measured) {
    system_->set_mark_sampled(true);
    const bool shared_after = share && system_->fingerprint(fp_after);
    const SpanLevels& after = popin_levels(mb, share, shared_after ? &fp_after : nullptr, true, lv_after_);
    const bool share_frame = shared_after && (!has_before || shared_before);
    PopinFrame pf;
    if (share_frame && share->find_frame(has_before, fp_before, fp_after, num_levels_, pf)) {
      ++share_counts_.frames_shared;
    } else {
      pf = popin_stats(mb, after, before, num_levels_);
      if (share_frame) share->publish_frame(has_before, fp_before, fp_after, num_levels_, pf);
    }
    row.measured = true;
    row.samples = static_cast<std::uint32_t>(pf.samples);
    row.blurry = static_cast<std::uint32_t>(pf.blurry);
    row.deficit_sum = pf.mean_deficit * static_cast<double>(pf.samples);
    row.pops = static_cast<std::uint32_t>(pf.visible_pops);
  }
  const PipelineCounters& c1 = pipe_->counters();
  row.clamp = clamp_;
  row.bias = bias_;
  row.finest_needed = rt_->finest_needed();
  row.disk_bytes = c1.disk_bytes - c0_.disk_bytes;
  row.decoded_bytes = c1.decoded_bytes - c0_.decoded_bytes;
  row.needs = static_cast<std::uint32_t>(rt_->needs());
  row.live_requests = static_cast<std::uint32_t>(pipe_->live_requests());
  row.ram_bytes = pipe_->ram_bytes_used();
  row.throttled_needs = system_->throttled_needs();
  row.produced = static_cast<std::uint32_t>(c1.produced - c0_.produced);
  row.produce_ms = static_cast<double>(c1.produce_ns - c0_.produce_ns) * 1e-6;
  system_->frame_counters(row.system);
  if (env_.timeline) {  // the uploads the system refused (stale), evictions, first samples
    for (const UploadItem& u : uploads) env_.timeline->on_upload_if_stale(u, frame_, now_);
    env_.timeline->end_frame(frame_, now_, *system_, row.measured,
                             row.samples ? static_cast<double>(row.blurry) / static_cast<double>(row.samples) : 0.0);
  }
  res_.metrics.add_frame(row);
}

ReplayResult SystemRun::summarize(const RunCost& cost) {
  nlohmann::json& s = res_.summary;
  fill_run_summary(s, {cfg_, plan_, env_.clock_name, *pipe_, *system_, res_.metrics, level_upload_, now_, sim_});
  if (cfg_.metrics.opt) add_cache_bounds(s);
  if (env_.on_finish) env_.on_finish(*system_);
  s["run"] = {{"wall_s", cost.wall_s},
              {"render_threads", cost.render_threads},
              {"loop_cpu_s", cost.loop_cpu_s},
              {"frames_per_s", cost.wall_s > 0 ? plan_.frames / cost.wall_s : 0.0},
              {"x_realtime", cost.wall_s > 0 ? plan_.duration_s / cost.wall_s : 0.0},
              {"peak_rss_MB", peak_rss_MB()}};
  return std::move(res_);
}

}  // namespace vtsim
