#include "sim/run/timeline.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>

#include "core/error.h"
#include "stream/system/i_system.h"

namespace vtsim {

namespace {

// Processes of the Trace Event file, one per stage, in pipeline order (their sort index).
enum Pid : int {
  kFrames = 1,
  kRequest,
  kQueue,
  kRead,
  kDecodeWait,
  kDecode,
  kUploadWait,
  kUpload,
  kSampled,
  kEvicted,
  kPids
};
constexpr const char* kPidName[kPids] = {"",       "frames",      "request", "queue",         "read",
                                         "decode wait", "decode", "upload wait", "upload", "first sampled",
                                         "evicted"};

// Ticks (ns) as microseconds with three decimals: exact and the same on every machine.
std::string us(Ticks t) {
  const bool neg = t < 0;
  const std::uint64_t a = neg ? static_cast<std::uint64_t>(-t) : static_cast<std::uint64_t>(t);
  return fmt::format("{}{}.{:03}", neg ? "-" : "", a / 1000, a % 1000);
}

std::string tile_name(TileKey k) { return fmt::format("L{} l{} ({},{})", k.layer(), k.level(), k.x(), k.y()); }

const char* unserved_name(Unserved w) {
  switch (w) {
    case Unserved::cancelled: return "cancelled";
    case Unserved::failed: return "failed";
    case Unserved::open_at_end: return "open at end";
    case Unserved::stale: return "stale";
  }
  return "?";
}

struct Slice {
  int pid = 0;
  const char* name = "";
  Ticks start = 0, dur = 0;
  std::string args;         // the JSON object's members, without braces
  std::uint64_t flow_s = 0;  // a flow arrow starts here (life id)
  std::uint64_t flow_f = 0;  // one ends here
  int lane = 0;
};

// Lanes: per stage, slices by start time, each to the lowest lane free at its start (a lane is
// free once its last slice ended; two slices that both start at a lane's end share it only if the
// earlier one had a duration). Sets each slice's lane and each stage's lane count; returns the
// slices' order (by stage, then start).
std::vector<std::size_t> assign_lanes(std::vector<Slice>& slices, int (&lanes_of)[kPids]) {
  std::vector<std::size_t> order(slices.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    const Slice& x = slices[a];
    const Slice& y = slices[b];
    if (x.pid != y.pid) return x.pid < y.pid;
    return x.start < y.start;
  });
  std::vector<Ticks> lane_end, lane_start;
  int pid = -1;
  for (const std::size_t i : order) {
    Slice& s = slices[i];
    if (s.pid != pid) {
      pid = s.pid;
      lane_end.clear();
      lane_start.clear();
    }
    std::size_t lane = 0;
    while (lane < lane_end.size() && !(lane_end[lane] < s.start || (lane_end[lane] == s.start && lane_start[lane] < s.start)))
      ++lane;
    if (lane == lane_end.size()) {
      lane_end.push_back(0);
      lane_start.push_back(0);
    }
    lane_end[lane] = s.start + s.dur;
    lane_start[lane] = s.start;
    s.lane = static_cast<int>(lane);
    lanes_of[pid] = std::max(lanes_of[pid], static_cast<int>(lane) + 1);
  }
  return order;
}

}  // namespace

void parse_timeline_frames(const std::string& flag, const std::string& text, TimelineOptions& out) {
  const auto colon = text.find(':');
  const auto num = [&](std::string_view s, int& v) {
    const auto* end = s.data() + s.size();
    const auto r = std::from_chars(s.data(), end, v);
    return !s.empty() && r.ec == std::errc() && r.ptr == end && v >= 0;
  };
  int a = 0, b = std::numeric_limits<int>::max();
  const std::string_view sv(text);
  const bool ok = colon != std::string::npos && num(sv.substr(0, colon), a) &&
                  (colon + 1 == text.size() || num(sv.substr(colon + 1), b));
  if (!ok) throw InputError(flag, fmt::format("'{}' is not a frame range A:B (frames A to B, 0-based, inclusive; A: to the end)", text));
  if (b < a) throw InputError(flag, fmt::format("'{}': the last frame {} is before the first {}", text, b, a));
  out.first_frame = a;
  out.last_frame = b;
}

TimelineEstimate estimate_timeline(const ReplayConfig& cfg, int frames, const TimelineOptions& opt) {
  TimelineEstimate e;
  std::uint64_t min_tile = 0;
  for (const auto& L : cfg.texture.layers.specs) {
    const std::uint64_t b = tile_decoded_bytes(cfg, L);
    if (b > 0) min_tile = min_tile ? std::min(min_tile, b) : b;
  }
  if (cfg.upload.tiles_per_frame > 0) {
    e.tiles_per_frame = static_cast<std::uint64_t>(cfg.upload.tiles_per_frame);
    e.budget = "upload.tiles_per_frame";
  }
  if (cfg.upload.bytes_per_frame > 0 && min_tile > 0) {
    const std::uint64_t t = static_cast<std::uint64_t>(cfg.upload.bytes_per_frame) / min_tile;
    if (e.tiles_per_frame == 0 || t < e.tiles_per_frame) {
      e.tiles_per_frame = std::max<std::uint64_t>(1, t);
      e.budget = fmt::format("upload.bytes_per_frame over a {}-byte tile", min_tile);
    }
  }
  if (e.tiles_per_frame == 0) {
    e.tiles_per_frame = 64;
    e.budget = "no upload budget: 64 assumed";
  }
  const int last = std::min(frames - 1, opt.last_frame);
  const std::uint64_t n = last >= opt.first_frame ? static_cast<std::uint64_t>(last - opt.first_frame + 1) : 0;
  e.bytes_per_frame = kTimelineFrameBytes + e.tiles_per_frame * kTimelineLifeBytes;
  e.bytes = n * e.bytes_per_frame;
  e.max_frames = opt.max_bytes / e.bytes_per_frame;
  return e;
}

void check_timeline_bound(const ReplayConfig& cfg, int frames, const TimelineOptions& opt) {
  const TimelineEstimate e = estimate_timeline(cfg, frames, opt);
  if (e.bytes <= opt.max_bytes) return;
  const int first = std::min(opt.first_frame, std::max(0, frames - 1));
  throw InputError("--timeline",
                   fmt::format("the timeline of frames {}..{} could reach {:.1f} MB, over its bound of {:.1f} MB ({} bytes a frame "
                               "at most: {} tiles a frame ({}) of at most {} bytes each): use --timeline-frames {}:{} ({} frames "
                               "fit), or raise the bound with --timeline-max-MB",
                               opt.first_frame, std::min(frames - 1, opt.last_frame), static_cast<double>(e.bytes) / 1e6,
                               static_cast<double>(opt.max_bytes) / 1e6, e.bytes_per_frame, e.tiles_per_frame, e.budget,
                               kTimelineLifeBytes, first, first + static_cast<int>(std::max<std::uint64_t>(1, e.max_frames)) - 1,
                               e.max_frames));
}

void TimelineRecorder::begin_run(double period_s, std::string clock, std::string trace_name) {
  period_s_ = period_s;
  clock_ = std::move(clock);
  trace_name_ = std::move(trace_name);
}

TileLife* TimelineRecorder::open_life(TileKey key) {
  const auto it = open_.find(key);
  return it == open_.end() ? nullptr : &lives_[it->second];
}

void TimelineRecorder::close(TileLife& life) {
  life.done = true;
  const auto it = open_.find(life.key);
  if (it != open_.end() && &lives_[it->second] == &life) open_.erase(it);
}

void TimelineRecorder::on_request(TileKey key, int frame, Ticks now, bool ram_hit, bool produced) {
  if (TileLife* old = open_life(key)) close(*old);  // needed again before its last life ended
  if (!in_range(frame)) return;
  TileLife l;
  l.id = lives_.size() + 1;
  l.key = key;
  l.frame = frame;
  l.request = now;
  l.ram_hit = ram_hit;
  l.produced = produced;
  if (ram_hit) l.in_ram = now;
  open_.emplace(key, lives_.size());
  lives_.push_back(l);
}

void TimelineRecorder::on_job(const JobResult& r, bool prefetch, bool produced) {
  TileLife* l = prefetch ? nullptr : open_life(r.key);
  if (!l && !in_range(frame_)) return;
  Job j;
  j.r = r;
  j.r.data.reset();  // the real clock's tile bytes: not the timeline's to keep
  j.life = l ? l->id : 0;
  j.prefetch = prefetch;
  j.produced = produced;
  j.frame = frame_;
  jobs_.push_back(std::move(j));
  if (!l) return;
  ++l->jobs;
  l->read_start = r.read_start;
  l->read_end = r.read_end;
  l->decode_start = r.decode_start;
  l->decode_end = r.decode_end;
  if (r.outcome == JobOutcome::ready) l->in_ram = r.decode_end;
}

void TimelineRecorder::on_unserved(TileKey key, Ticks end, Unserved why) {
  TileLife* l = open_life(key);
  if (!l) return;
  l->ended = end;
  l->why = why;
  close(*l);
}

void TimelineRecorder::on_upload(const UploadItem& u, int frame, Ticks now, Ticks transfer, bool accepted) {
  TileLife* l = open_life(u.key);
  if (!l) return;
  l->in_ram = now - u.ram_ticks;
  l->upload_start = now;
  l->upload_end = now + transfer;
  l->upload_frame = frame;
  l->bytes = u.bytes;
  if (accepted) {
    pending_.push_back(static_cast<std::size_t>(l - lives_.data()));
  } else {
    l->stale = true;
    l->ended = now;
    l->why = Unserved::stale;
    close(*l);
  }
}

void TimelineRecorder::end_frame(int frame, Ticks now, const IStreamingSystem& system, bool measured, double blurry_fraction) {
  for (const TileKey k : evict_log_) {
    TileLife* l = open_life(k);
    if (l && l->upload_start < 0) l = nullptr;  // a new request for the key, not what was resident
    if (l) {
      l->evicted = now;
      l->evicted_frame = frame;
      close(*l);
    }
    if (l || in_range(frame)) evictions_.push_back({k, frame, now, l ? l->id : 0});
  }
  evict_log_.clear();
  if (measured) {
    std::size_t w = 0;
    for (const std::size_t i : pending_) {
      TileLife& l = lives_[i];
      if (l.done) continue;
      const int s = system.tile_sampled(l.key);
      if (s == 0) {
        pending_[w++] = i;
      } else {
        if (s == 1) {
          l.sampled = now;
          l.sampled_frame = frame;
        }
        close(l);  // sampled, or left VRAM unsampled without an eviction (a clipmap window moved on)
      }
    }
    pending_.resize(w);
  }
  if (in_range(frame)) frames_.push_back({frame, now, measured, blurry_fraction});
  // The bound during the run: the estimate before it assumed the upload budget's tiles a frame; a
  // start-up fill or a cut requests more at once. Each life, job and frame at its upper size.
  const std::uint64_t bound = lives_.size() * kTimelineLifeBytes + jobs_.size() * kTimelineJobBytes +
                              evictions_.size() * kTimelineEvictionBytes + frames_.size() * kTimelineFrameBytes;
  if (bound > opt_.max_bytes)
    throw InputError("--timeline", fmt::format("the timeline passed its bound of {:.1f} MB at frame {} ({} tile requests since frame {}; "
                                               "a start-up fill or a cut requests many tiles at once): use --timeline-frames A:B to "
                                               "record fewer frames, or raise the bound with --timeline-max-MB",
                                               static_cast<double>(opt_.max_bytes) / 1e6, frame, lives_.size(), opt_.first_frame));
}

TimelineRecorder::Counts TimelineRecorder::counts() const {
  Counts c;
  c.requests = lives_.size();
  for (const Job& j : jobs_) {
    c.reads += j.r.bytes_read > 0;
    const bool ready = j.r.outcome == JobOutcome::ready;
    c.decodes += ready && !j.produced;
    c.produced += ready && j.produced;
  }
  for (const TileLife& l : lives_) {
    c.uploads += l.upload_start >= 0;
    c.first_sampled += l.sampled >= 0;
  }
  c.evictions = evictions_.size();
  return c;
}

std::string TimelineRecorder::json() const {
  const Ticks period = seconds_to_ticks(period_s_);
  std::vector<Slice> slices;
  slices.reserve(lives_.size() * 6 + jobs_.size() * 3 + frames_.size());
  const auto life_args = [](const TileLife& l) {
    return fmt::format("\"tile\":\"{}\",\"life\":{},\"frame\":{}", tile_name(l.key), l.id, l.frame);
  };
  for (std::size_t i = 0; i < frames_.size(); ++i) {
    const FrameMark& f = frames_[i];
    std::string a = fmt::format("\"frame\":{}", f.frame);
    if (f.measured) a += fmt::format(",\"blurry\":{:.4f}", f.blurry);
    // Until the next frame starts (the real clock's frames run late; ticks round): one track.
    const Ticks dur = i + 1 < frames_.size() && frames_[i + 1].frame == f.frame + 1 ? frames_[i + 1].start - f.start : period;
    slices.push_back({kFrames, "frame", f.start, dur, std::move(a)});
  }
  for (const TileLife& l : lives_) {
    const std::string a = life_args(l);
    const auto add = [&](int pid, const char* name, Ticks start, Ticks end, const std::string& extra = {}) {
      slices.push_back({pid, name, start, std::max<Ticks>(0, end - start), extra.empty() ? a : a + "," + extra});
      return slices.size() - 1;
    };
    // The life's first slice with a duration: its flow arrow starts there.
    constexpr std::size_t kNone = static_cast<std::size_t>(-1);
    std::size_t first = kNone;
    const auto starts_flow = [&](std::size_t i) {
      if (first == kNone && slices[i].dur > 0) first = i;
    };
    // Queue: the request until the job that brought it started (or until it was dropped).
    if (!l.ram_hit) {
      const Ticks q_end = l.produced ? l.decode_start : l.read_start;
      if (q_end >= 0) starts_flow(add(kQueue, "queue", l.request, q_end));
      else if (l.ended >= 0) starts_flow(add(kQueue, "queue", l.request, l.ended, fmt::format("\"ended\":\"{}\"", unserved_name(l.why))));
    }
    if (l.in_ram >= 0) {
      const Ticks end = l.upload_start >= 0 ? l.upload_start : l.ended;
      if (end >= 0) starts_flow(add(kUploadWait, "upload wait", l.in_ram, end, l.ram_hit ? "\"ram_hit\":true" : ""));
    }
    if (l.upload_start >= 0)
      starts_flow(add(kUpload, "upload", l.upload_start, l.upload_end,
                      fmt::format("\"bytes\":{}{}", l.bytes, l.stale ? ",\"stale\":true" : "")));
    if (l.sampled >= 0) {
      const std::size_t s = add(kSampled, "first sampled", l.sampled, l.sampled + period,
                                fmt::format("\"latency_ms\":{:.3f}", ticks_to_ms(l.sampled - l.request)));
      if (first != kNone) {
        slices[first].flow_s = l.id;
        slices[s].flow_f = l.id;
      }
    }
  }
  for (const Job& j : jobs_) {
    const JobResult& r = j.r;
    std::string a = fmt::format("\"tile\":\"{}\",\"life\":{},\"frame\":{}", tile_name(r.key), j.life, j.frame);
    if (j.prefetch) a += ",\"prefetch\":true";
    if (r.outcome != JobOutcome::ready)
      a += fmt::format(",\"outcome\":\"{}\"", r.outcome == JobOutcome::cancelled ? "cancelled" : fault_name(r.fault));
    const bool produced = j.produced;
    if (r.bytes_read > 0)
      slices.push_back({kRead, "read", r.read_start, std::max<Ticks>(0, r.read_end - r.read_start),
                        a + fmt::format(",\"bytes\":{}", r.bytes_read)});
    if (r.outcome != JobOutcome::ready) continue;
    if (produced) {
      slices.push_back({kDecode, "produce", r.decode_start, std::max<Ticks>(0, r.decode_end - r.decode_start),
                        a + fmt::format(",\"bytes\":{}", r.decoded_bytes)});
      continue;
    }
    if (r.decode_start > r.read_end) slices.push_back({kDecodeWait, "decode wait", r.read_end, r.decode_start - r.read_end, a});
    slices.push_back({kDecode, "decode", r.decode_start, std::max<Ticks>(0, r.decode_end - r.decode_start),
                      a + fmt::format(",\"bytes\":{}", r.decoded_bytes)});
  }
  int lanes_of[kPids] = {};
  const std::vector<std::size_t> order = assign_lanes(slices, lanes_of);
  std::string out;
  out.reserve(slices.size() * 150 + lives_.size() * 120 + 4096);
  out += "{\"displayTimeUnit\":\"ms\",\"otherData\":{";
  out += fmt::format("\"producer\":\"vtsim replay --timeline\",\"clock\":\"{}\",\"trace\":{},\"frame_period_ms\":{:.6f},"
                     "\"frames\":[{},{}]",
                     clock_, nlohmann::json(trace_name_).dump(), period_s_ * 1e3, frames_.empty() ? 0 : frames_.front().frame,
                     frames_.empty() ? -1 : frames_.back().frame);
  out += "},\"traceEvents\":[\n";
  bool first_event = true;
  const auto emit = [&](const std::string& e) {
    if (!first_event) out += ",\n";
    first_event = false;
    out += e;
  };
  lanes_of[kRequest] = std::max(lanes_of[kRequest], 1);
  lanes_of[kEvicted] = std::max(lanes_of[kEvicted], 1);
  for (int p = 1; p < kPids; ++p) {
    emit(fmt::format("{{\"name\":\"process_name\",\"ph\":\"M\",\"pid\":{},\"args\":{{\"name\":\"{}\"}}}}", p, kPidName[p]));
    emit(fmt::format("{{\"name\":\"process_sort_index\",\"ph\":\"M\",\"pid\":{},\"args\":{{\"sort_index\":{}}}}}", p, p));
    for (int t = 0; t < lanes_of[p]; ++t)
      emit(fmt::format("{{\"name\":\"thread_name\",\"ph\":\"M\",\"pid\":{},\"tid\":{},\"args\":{{\"name\":\"{} {}\"}}}}", p, t + 1,
                       kPidName[p], t));
  }
  for (const TileLife& l : lives_)
    emit(fmt::format("{{\"name\":\"request\",\"cat\":\"tile\",\"ph\":\"i\",\"s\":\"t\",\"ts\":{},\"pid\":{},\"tid\":1,\"args\":{{{}{}{}}}}}",
                     us(l.request), static_cast<int>(kRequest), life_args(l), l.ram_hit ? ",\"ram_hit\":true" : "",
                     l.produced ? ",\"produced\":true" : ""));
  for (const std::size_t i : order) {
    const Slice& s = slices[i];
    emit(fmt::format("{{\"name\":\"{}\",\"cat\":\"tile\",\"ph\":\"X\",\"ts\":{},\"dur\":{},\"pid\":{},\"tid\":{},\"args\":{{{}}}}}", s.name,
                     us(s.start), us(s.dur), s.pid, s.lane + 1, s.args));
    // Flow arrows bind to the slice enclosing their time: its middle.
    if (s.flow_s)
      emit(fmt::format("{{\"name\":\"tile\",\"cat\":\"flow\",\"ph\":\"s\",\"id\":{},\"ts\":{},\"pid\":{},\"tid\":{}}}", s.flow_s,
                       us(s.start + s.dur / 2), s.pid, s.lane + 1));
    if (s.flow_f)
      emit(fmt::format("{{\"name\":\"tile\",\"cat\":\"flow\",\"ph\":\"f\",\"bp\":\"e\",\"id\":{},\"ts\":{},\"pid\":{},\"tid\":{}}}",
                       s.flow_f, us(s.start + s.dur / 2), s.pid, s.lane + 1));
  }
  for (const Eviction& e : evictions_)
    emit(fmt::format("{{\"name\":\"evicted\",\"cat\":\"tile\",\"ph\":\"i\",\"s\":\"t\",\"ts\":{},\"pid\":{},\"tid\":1,\"args\":{{\"tile\":"
                     "\"{}\",\"life\":{},\"frame\":{}}}}}",
                     us(e.t), static_cast<int>(kEvicted), tile_name(e.key), e.life, e.frame));
  out += "\n]}\n";
  if (out.size() > opt_.max_bytes)
    throw InputError("--timeline", fmt::format("the timeline is {:.1f} MB, over its bound of {:.1f} MB: use --timeline-frames A:B to "
                                               "record fewer frames, or raise the bound with --timeline-max-MB",
                                               static_cast<double>(out.size()) / 1e6, static_cast<double>(opt_.max_bytes) / 1e6));
  return out;
}

}  // namespace vtsim
