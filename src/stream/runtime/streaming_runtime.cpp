#include "stream/runtime/streaming_runtime.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>

namespace vtsim {

namespace {

std::string key_text(TileKey k) { return fmt::format("tile (layer {}, level {}, x {}, y {})", k.layer(), k.level(), k.x(), k.y()); }

}  // namespace

StreamingRuntime::StreamingRuntime(RuntimeParts parts) : parts_(std::move(parts)) {
  if (!parts_.system || !parts_.throttle) throw std::invalid_argument("StreamingRuntime: a system and a throttle policy are required");
  if (parts_.owned_executor) parts_.executor = parts_.owned_executor.get();
  if (!parts_.executor) throw std::invalid_argument("StreamingRuntime: an executor is required");
  if (!parts_.sizer) throw std::invalid_argument("StreamingRuntime: a tile sizer is required");
  if (parts_.tile_size < 1 || parts_.layers < 1 || parts_.extent.width < 1 || parts_.extent.height < 1)
    throw std::invalid_argument("StreamingRuntime: an empty texture");
  sys_ = parts_.system.get();
  exec_ = parts_.executor;
  pipe_ = std::make_unique<Pipeline>(parts_.pipeline, *exec_, parts_.sizer);
  budget_ = parts_.budget;
  service_ = parts_.service_Bps;
  num_levels_ = sys_->num_levels();
  finest_needed_ = num_levels_;
  // Tiles a side per level, as the systems halve a level (rounding up) down to the coarsest.
  std::int64_t w = parts_.extent.width, h = parts_.extent.height;
  const std::int64_t T = parts_.tile_size;
  for (int l = 0; l < num_levels_; ++l) {
    tiles_x_.push_back((w + T - 1) / T);
    tiles_y_.push_back((h + T - 1) / T);
    w = std::max<std::int64_t>(1, (w + 1) / 2);
    h = std::max<std::int64_t>(1, (h + 1) / 2);
  }
  sys_->record_page_table(&pt_log_);
  requests_.block_shift = std::bit_width(static_cast<unsigned>(parts_.tile_size)) - 1;
  requests_.keep_samples = true;
  requests_.levels = num_levels_;
  requests_.divisor = 1;
}

StreamingRuntime::~StreamingRuntime() { sys_->record_page_table(nullptr); }

void StreamingRuntime::require(Phase p, const char* call) const {
  if (phase_ == p) return;
  switch (phase_) {
    case Phase::idle:
      throw RuntimeCallError(call, "no frame is begun (call begin_frame first)");
    case Phase::begun:
      throw RuntimeCallError(call, fmt::format("frame {} is begun and not ended (call end_frame first)", frame_));
    case Phase::planned:
      throw RuntimeCallError(call, fmt::format("frame {}'s uploads are planned and not committed (call commit_uploads)", frame_));
  }
}

void StreamingRuntime::begin_frame(Ticks now) {
  require(Phase::idle, "begin_frame");
  if (frame_ >= 0 && now < now_)
    throw RuntimeCallError("begin_frame", fmt::format("time {} ns is before the previous frame's {} ns", now, now_));
  ++frame_;
  now_ = now;
  phase_ = Phase::begun;
  spans_ = nullptr;
  have_requests_ = false;
  requests_.spans.clear();
  requests_.view.samples.clear();
  requests_.samples = 0;
  updates_.page_table.clear();
  updates_.windows.clear();
  pipe_->begin_frame(frame_, now);
}

void StreamingRuntime::set_camera(const Pose& pose, const glm::dvec3& velocity_mps, bool cut) {
  require(Phase::begun, "set_camera");
  own_pose_ = pose;
  pose_ = &own_pose_;
  velocity_ = velocity_mps;
  cut_ = cut;
}

void StreamingRuntime::request(TileKey key) {
  require(Phase::begun, "request");
  const int l = static_cast<int>(key.level());
  if (static_cast<int>(key.layer()) >= parts_.layers)
    throw RuntimeCallError("request", fmt::format("{}: the texture has {} layer(s)", key_text(key), parts_.layers));
  if (l >= num_levels_)
    throw RuntimeCallError("request", fmt::format("{}: the texture has {} levels", key_text(key), num_levels_));
  const auto li = static_cast<std::size_t>(l);
  if (key.x() >= tiles_x_[li] || key.y() >= tiles_y_[li])
    throw RuntimeCallError("request", fmt::format("{} is outside the texture: level {} is {}×{} tiles", key_text(key), l,
                                                  tiles_x_[li], tiles_y_[li]));
  if (spans_) throw RuntimeCallError("request", "this frame's feedback is a span buffer (set_feedback): requests add nothing to it");
  // One sample at the tile's centre texel, at its level (lod l + 0.5: desired level l).
  const std::int64_t T = parts_.tile_size;
  ViewSample s;
  s.u = std::min<std::int64_t>((key.x() * T + T / 2) << l, parts_.extent.width - 1);
  s.v = std::min<std::int64_t>((key.y() * T + T / 2) << l, parts_.extent.height - 1);
  s.lod = static_cast<float>(l) + 0.5f;
  s.pixel = static_cast<std::uint32_t>(requests_.view.samples.size());
  ViewSpan sp;
  sp.u_lo = sp.u_hi = s.u;
  sp.v_lo = sp.v_hi = s.v;
  sp.pixel = sp.first = s.pixel;
  sp.count = 1;
  sp.level = l;
  requests_.view.samples.push_back(s);
  requests_.spans.push_back(sp);
  have_requests_ = true;
}

void StreamingRuntime::set_feedback(SpanBuffer& spans, bool fresh) {
  require(Phase::begun, "set_feedback");
  if (have_requests_) throw RuntimeCallError("set_feedback", "this frame already has request()s: give one kind of feedback a frame");
  // A span that straddles a page is expanded into its samples: from the buffer's own, or
  // re-rendered by the scene that rendered it (core/view_spans.h).
  if (!spans.has_samples && !spans.scene)
    throw RuntimeCallError("set_feedback", "the span buffer has neither its samples (has_samples) nor the scene that rendered it "
                                           "(scene): fill one, or hand the feedback as request()s");
  spans_ = &spans;
  if (fresh) finest_needed_ = finest_level(spans, num_levels_);
}

SpanBuffer& StreamingRuntime::request_buffer() {
  SpanBuffer& b = requests_;
  const auto n = static_cast<int>(b.view.samples.size());
  b.width = b.view.width = std::max(1, n);
  b.height = b.view.height = 1;
  b.samples = static_cast<std::uint64_t>(n);
  b.has_samples = true;
  finest_needed_ = finest_level(b, num_levels_);
  return b;
}

void StreamingRuntime::plan_uploads() {
  require(Phase::begun, "end_frame");
  SpanBuffer* fb = spans_;
  if (!fb) fb = &request_buffer();  // requests, or none (an empty buffer: nothing visible)
  if (!pose_) {
    sys_->clip_windows(windows_);
    if (!windows_.empty()) throw RuntimeCallError("end_frame", "a clipmap follows the camera: call set_camera every frame");
  }
  if (sys_->wants_samples()) materialise_samples(*fb);
  const SystemFrame sf{frame_, now_, pose_, cut_ ? glm::dvec3(0.0) : velocity_, fb->has_samples ? &fb->view : nullptr,
                       finest_needed_, fb};
  sys_->begin_frame(sf);
  sys_->missing_bytes_by_level(missing_);
  ThrottleInput ti;
  ti.frame = frame_;
  ti.now = now_;
  ti.frame_period_s = parts_.frame_period_s;
  ti.num_levels = num_levels_;
  ti.finest_needed = finest_needed_;
  ti.coarsest_clamp = sys_->coarsest_clamp();
  ti.missing_bytes_by_level = missing_;
  ti.service_Bps = service_;
  ti.discontinuity = cut_;
  ti.pool_occupancy = sys_->pool_occupancy();
  ti.pool_pressure = sys_->pool_pressure();
  sys_->pool_demand(ti.pool_demand_by_level, ti.pool_slots);
  ThrottleDecision dec = parts_.throttle->update(ti);
  updates_.frame = frame_;
  updates_.throttle_changed = dec.clamp != clamp_ || dec.bias != bias_;
  updates_.reason = std::move(dec.reason);
  clamp_ = dec.clamp;
  bias_ = dec.bias;
  sample_bias_ = dec.sample_bias;
  updates_.clamp = clamp_;
  updates_.feedback_bias = bias_;
  updates_.sample_bias = sample_bias_;
  sys_->apply_throttle(dec);

  needs_.clear();
  sys_->emit_needs(needs_);
  pipe_->set_needs(needs_);
  pipe_->dispatch();
  uploads_.clear();
  pipe_->take_uploads(budget_, uploads_);
  phase_ = Phase::planned;
}

const FrameUpdates& StreamingRuntime::commit_uploads(IUploadSink& sink) {
  require(Phase::planned, "commit_uploads");
  phase_ = Phase::idle;  // whatever happens below, the frame ends here
  updates_.uploads = 0;
  updates_.upload_bytes = 0;
  updates_.stale = 0;
  updates_.stale_needed.clear();
  for (std::size_t i = 0; i < uploads_.size(); ++i) {
    const UploadItem& u = uploads_[i];
    if (!sys_->accepts(u.key)) {
      sys_->commit(u.key, frame_);  // refused: counted stale by the system
      ++updates_.stale;
      updates_.stale_needed.push_back(u.needed_time);
      continue;
    }
    const TileUpload tu{u.key, sys_->vram_slot(u.key), u.data.get(), &u};
    try {
      sink.upload(tu);
    } catch (...) {
      std::string what = "an exception that is not a std::exception";
      try {
        throw;
      } catch (const std::exception& e) {
        what = e.what();
      } catch (...) {
      }
      // Nothing is lost: this tile and the ones not yet offered go back to the upload queue.
      // The page-table and window changes of the tiles committed before it are reported by the
      // next end_frame.
      const std::string msg = fmt::format("the upload callback threw for {}: {}; it and the {} tile(s) after it in frame {} "
                                          "are queued again",
                                          key_text(u.key), what, uploads_.size() - i - 1, frame_);
      pipe_->return_uploads(uploads_.begin() + static_cast<std::ptrdiff_t>(i), uploads_.end());
      uploads_.erase(uploads_.begin() + static_cast<std::ptrdiff_t>(i), uploads_.end());
      throw RuntimeCallError("end_frame", msg);
    }
    if (!sys_->commit(u.key, frame_)) throw std::logic_error("StreamingRuntime: commit refused a tile accepts() took");
    ++updates_.uploads;
    updates_.upload_bytes += u.bytes;
  }
  updates_.page_table.swap(pt_log_);
  pt_log_.clear();
  sys_->clip_windows(windows_);
  for (std::size_t l = 0; l < windows_.size(); ++l)
    if (l >= last_windows_.size() || !(windows_[l] == last_windows_[l]))
      updates_.windows.push_back({static_cast<int>(l), windows_[l]});
  last_windows_.swap(windows_);
  return updates_;
}

const FrameUpdates& StreamingRuntime::end_frame(IUploadSink& sink) {
  require(Phase::begun, "end_frame");
  plan_uploads();
  return commit_uploads(sink);
}

}  // namespace vtsim
