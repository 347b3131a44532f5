#include "sim/run/metrics.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>

#include "core/error.h"

namespace vtsim {

TileLatency upload_latency(const UploadItem& u, Ticks now, int frame, Ticks upload) {
  TileLatency lat;
  lat.needed = u.needed_time;
  lat.total = now - u.needed_time;
  lat.frames = frame - u.needed_frame;
  lat.queue = u.queue_ticks;
  lat.io = u.io_ticks;
  lat.decode_wait = u.decode_wait_ticks;
  lat.decode = u.decode_ticks;
  lat.upload_wait = u.ram_ticks;
  lat.upload = upload;
  lat.level = static_cast<std::uint8_t>(u.key.level());
  lat.ram_hit = u.ram_hit;
  return lat;
}

Percentiles percentiles(std::vector<double> v) {
  Percentiles p;
  p.count = v.size();
  if (v.empty()) return p;
  std::sort(v.begin(), v.end());
  // Nearest rank: the smallest value with at least q of the data at or below it.
  auto rank = [&](double q) {
    const auto k = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())));
    return v[std::min(v.size() - 1, k == 0 ? 0 : k - 1)];
  };
  p.p50 = rank(0.50);
  p.p95 = rank(0.95);
  p.p99 = rank(0.99);
  p.max = v.back();
  double s = 0;
  for (double x : v) s += x;
  p.mean = s / static_cast<double>(v.size());
  return p;
}

nlohmann::json to_json(const Percentiles& p) {
  return {{"p50", p.p50}, {"p95", p.p95}, {"p99", p.p99}, {"max", p.max}, {"mean", p.mean}, {"count", p.count}};
}

void MetricsCollector::add_level_bytes(int level, std::uint64_t disk, std::uint64_t upload) {
  const auto l = static_cast<std::size_t>(level);
  if (level_disk_.size() <= l) {
    level_disk_.resize(l + 1, 0);
    level_upload_.resize(l + 1, 0);
  }
  level_disk_[l] += disk;
  level_upload_[l] += upload;
}

std::vector<std::optional<double>> km_quantiles(std::vector<double> events, std::vector<double> censored,
                                                const std::vector<double>& qs) {
  std::vector<std::optional<double>> out(qs.size());
  std::sort(events.begin(), events.end());
  std::sort(censored.begin(), censored.end());
  double at_risk = static_cast<double>(events.size() + censored.size());
  double survival = 1.0;
  std::size_t e = 0, c = 0;
  while (e < events.size()) {
    const double t = events[e];
    while (c < censored.size() && censored[c] < t) ++c, at_risk -= 1.0;  // censored before t: no longer at risk
    std::size_t d = 0;
    while (e < events.size() && events[e] == t) ++e, ++d;
    survival *= 1.0 - static_cast<double>(d) / at_risk;
    at_risk -= static_cast<double>(d);
    // 1e-12: the product of (1 − d/n) telescopes to (n − k)/n only up to rounding, so that without
    // censoring the quantile is the nearest-rank percentile exactly.
    for (std::size_t i = 0; i < qs.size(); ++i)
      if (!out[i] && 1.0 - survival >= qs[i] - 1e-12) out[i] = t;
  }
  return out;
}

nlohmann::json MetricsCollector::latency_json() const {
  std::vector<double> total, frames, queue, io, dwait, dec, uwait, up;
  std::size_t ram_hits = 0;
  const Ticks warm = seconds_to_ticks(warmup_s_);
  for (const auto& l : latencies_) {
    if (l.needed < warm) continue;  // the start-up fill's
    total.push_back(ticks_to_ms(l.total));
    frames.push_back(l.frames);
    queue.push_back(ticks_to_ms(l.queue));
    io.push_back(ticks_to_ms(l.io));
    dwait.push_back(ticks_to_ms(l.decode_wait));
    dec.push_back(ticks_to_ms(l.decode));
    uwait.push_back(ticks_to_ms(l.upload_wait));
    up.push_back(ticks_to_ms(l.upload));
    ram_hits += l.ram_hit;
  }
  std::vector<double> waits;
  std::size_t why[4] = {};
  for (const UnservedRequest& u : unserved_) {
    if (u.needed_time < warm) continue;
    waits.push_back(ticks_to_ms(u.end_time - u.needed_time));
    ++why[static_cast<int>(u.why) & 3];
  }
  nlohmann::json j = to_json(percentiles(total));
  j["frames"] = to_json(percentiles(frames));
  j["stages_ms"] = {{"queue", to_json(percentiles(queue))},        {"io", to_json(percentiles(io))},
                    {"decode_wait", to_json(percentiles(dwait))}, {"decode", to_json(percentiles(dec))},
                    {"upload_wait", to_json(percentiles(uwait))}, {"upload", to_json(percentiles(up))}};
  j["tiles"] = total.size();
  j["from_ram_cache"] = ram_hits;
  // Every demand request, served or not (docs/metrics.md, "Latency"): the served fraction, the
  // censored requests and their waits, and the Kaplan–Meier quantiles over all of them.
  const std::size_t requests = total.size() + waits.size();
  j["requests"] = requests;
  j["served_fraction"] = requests ? nlohmann::json(static_cast<double>(total.size()) / static_cast<double>(requests)) : nlohmann::json();
  j["censored"] = {{"count", waits.size()},
                   {"cancelled", why[static_cast<int>(Unserved::cancelled)]},
                   {"failed", why[static_cast<int>(Unserved::failed)]},
                   {"open_at_end", why[static_cast<int>(Unserved::open_at_end)]},
                   {"stale", why[static_cast<int>(Unserved::stale)]},
                   {"wait_ms", to_json(percentiles(waits))}};
  const auto km = km_quantiles(total, waits, {0.50, 0.95, 0.99});
  const auto opt = [](const std::optional<double>& v) { return v ? nlohmann::json(*v) : nlohmann::json(); };
  j["km"] = {{"p50", opt(km[0])}, {"p95", opt(km[1])}, {"p99", opt(km[2])}};
  return j;
}

nlohmann::json MetricsCollector::startup_json(double sharp_margin) const {
  std::size_t frames = 0, tiles = 0, tiles_to_sharp = 0;
  std::uint64_t disk = 0;
  // "Sharp" is as sharp as this run gets: within sharp_margin of the median blurry fraction of the
  // steady frames (a clipmap's outer rings stay coarser than wanted whatever loads: the demo's walk
  // settles at 19-33 % blurry, so an absolute bound would never be met).
  std::vector<double> steady;
  for (const auto& r : frames_)
    if (r.measured && r.samples > 0 && r.t_s >= warmup_s_) steady.push_back(static_cast<double>(r.blurry) / r.samples);
  const double sharp = percentiles(steady).p50 + sharp_margin;
  nlohmann::json first_sharp;  // null: never sharp
  for (const auto& r : frames_) {
    if (r.t_s < warmup_s_) {
      ++frames;
      tiles += r.uploads;
      disk += r.disk_bytes;
    }
    if (first_sharp.is_null()) {
      tiles_to_sharp += r.uploads;
      if (!steady.empty() && r.measured && r.samples > 0 && static_cast<double>(r.blurry) / r.samples <= sharp) first_sharp = r.t_s;
    }
  }
  return {{"warmup_s", warmup_s_},
          {"frames", frames},
          {"tiles", tiles},
          {"disk_read_bytes", disk},
          {"first_sharp_s", first_sharp},
          {"tiles_to_first_sharp", first_sharp.is_null() ? nlohmann::json() : nlohmann::json(tiles_to_sharp)}};
}

MetricsCollector::SteadyBytes MetricsCollector::steady_bytes(double duration_s) const {
  SteadyBytes b;
  double first = duration_s;
  for (const auto& r : frames_) {
    if (r.t_s < warmup_s_) continue;
    first = std::min(first, r.t_s);
    b.disk += r.disk_bytes;
    b.decoded += r.decoded_bytes;
    b.upload += r.upload_bytes;
  }
  b.duration_s = duration_s - first;
  return b;
}

nlohmann::json MetricsCollector::popin_json(double sharp_margin) const {
  std::vector<double> blurry;
  double deficit = 0.0, samples = 0.0;
  std::uint64_t pops = 0;
  for (const auto& r : frames_) {
    if (!r.measured || r.t_s < warmup_s_) continue;
    blurry.push_back(r.samples ? static_cast<double>(r.blurry) / r.samples : 0.0);
    deficit += r.deficit_sum;
    samples += r.samples;
    pops += r.pops;
  }
  const Percentiles bp = percentiles(blurry);
  // Time to sharp after each cut or fast turn: from the event frame to the first measured frame,
  // at or after the blurriest frame of the kPeakHorizon_s following the event, whose blurry
  // fraction is back within `sharp_margin` of the second before the event. Searching from the
  // peak matters for turns: the view is still sharp when the turn starts and blurs as it sweeps
  // over pages that are not resident (Yao 2011 §4), so the first frame alone would read "0 s".
  constexpr double kPeakHorizon_s = 3.0;  // a blur starting later is not this event's
  const auto bf_of = [](const FrameRow& r) { return r.samples ? static_cast<double>(r.blurry) / r.samples : 0.0; };
  std::vector<double> tts;
  std::size_t unresolved = 0;
  for (std::size_t e = 0; e < frames_.size(); ++e) {
    if (!frames_[e].event || frames_[e].t_s < warmup_s_) continue;
    const double te = frames_[e].t_s;
    double base = 0.0;
    int nb = 0;
    for (std::size_t k = e; k-- > 0 && frames_[k].t_s >= te - 1.0;) {
      if (frames_[k].event) break;
      if (!frames_[k].measured || frames_[k].samples == 0) continue;
      base += bf_of(frames_[k]);
      ++nb;
    }
    base = nb ? base / nb : 0.0;
    std::size_t end = e + 1;  // the event's window: up to the next event
    while (end < frames_.size() && !frames_[end].event) ++end;
    std::size_t peak = e;
    double peak_bf = -1.0;
    for (std::size_t f = e; f < end && frames_[f].t_s <= te + kPeakHorizon_s; ++f)
      if (frames_[f].measured && bf_of(frames_[f]) > peak_bf) peak_bf = bf_of(frames_[f]), peak = f;
    bool found = false;
    for (std::size_t f = peak; f < end; ++f) {
      const auto& r = frames_[f];
      if (!r.measured) continue;
      if (bf_of(r) <= base + sharp_margin) {
        tts.push_back(r.t_s - te);
        found = true;
        break;
      }
    }
    if (!found) ++unresolved;
  }
  const Percentiles tp = percentiles(tts);
  return {{"blurry_fraction_mean", bp.mean},
          {"blurry_fraction_p95", bp.p95},
          {"blurry_fraction_p99", bp.p99},
          {"blurry_fraction_max", bp.max},
          {"mean_deficit", samples > 0 ? deficit / samples : 0.0},
          {"visible_pops", pops},
          {"measured_frames", bp.count},
          // No event, or none that became sharp: no time to sharp (null), not 0 s.
          {"time_to_sharp_s", {{"events", tts.size() + unresolved},
                               {"mean", tts.empty() ? nlohmann::json() : nlohmann::json(tp.mean)},
                               {"max", tts.empty() ? nlohmann::json() : nlohmann::json(tp.max)},
                               {"never_sharp", unresolved}}}};
}

nlohmann::json MetricsCollector::upload_per_frame_json() const {
  std::vector<double> b, t;
  for (const auto& r : frames_) {
    if (r.t_s < warmup_s_) continue;
    b.push_back(static_cast<double>(r.upload_bytes));
    t.push_back(r.uploads);
  }
  const Percentiles pb = percentiles(b), pt = percentiles(t);
  return {{"bytes", {{"p50", pb.p50}, {"p99", pb.p99}, {"max", pb.max}, {"mean", pb.mean}}},
          {"tiles", {{"p50", pt.p50}, {"p99", pt.p99}, {"max", pt.max}, {"mean", pt.mean}}}};
}

nlohmann::json MetricsCollector::per_level_json(double duration_s) const {
  nlohmann::json a = nlohmann::json::array();
  for (std::size_t l = 0; l < level_disk_.size(); ++l) {
    if (!level_disk_[l] && !level_upload_[l]) continue;
    a.push_back({{"level", l},
                 {"disk_read_bytes", level_disk_[l]},
                 {"upload_bytes", level_upload_[l]},
                 {"disk_read_MBps", duration_s > 0 ? static_cast<double>(level_disk_[l]) / duration_s / 1e6 : 0.0},
                 {"upload_MBps", duration_s > 0 ? static_cast<double>(level_upload_[l]) / duration_s / 1e6 : 0.0}});
  }
  return a;
}

nlohmann::json MetricsCollector::throttle_json(std::size_t max_changes) const {
  std::size_t throttled = 0, needs_throttled = 0;
  int max_clamp = 0;
  for (const auto& r : frames_) {
    if (r.t_s < warmup_s_) continue;
    throttled += r.clamp > r.finest_needed;
    needs_throttled += r.throttled_needs;
    max_clamp = std::max(max_clamp, r.clamp);
  }
  nlohmann::json changes = nlohmann::json::array();
  for (std::size_t i = 0; i < throttle_.size() && i < max_changes; ++i) {
    const auto& c = throttle_[i];
    changes.push_back({{"frame", c.frame}, {"t_s", c.t_s}, {"from", c.from}, {"to", c.to}, {"bias", c.bias}, {"reason", c.reason}});
  }
  return {{"frames_throttled", throttled},
          {"requests_throttled", needs_throttled},
          {"max_clamp", max_clamp},
          {"changes", throttle_.size()},
          {"lod_timeline", changes},
          {"lod_timeline_truncated", throttle_.size() > max_changes}};
}

void MetricsCollector::set_system_columns(std::vector<std::string> names) {
  if (names.size() > kSystemCounters) throw std::invalid_argument("MetricsCollector: too many system columns");
  system_columns_ = std::move(names);
}

void MetricsCollector::write_frames_csv(const std::string& path) const {
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "wb"), &std::fclose);
  if (!f) throw InputError(path, "cannot open for writing");
  std::string header = "frame,t_s,clamp,bias,measured,samples,blurry_fraction,mean_deficit,pops,finest_needed,event,"
                       "disk_bytes,decoded_bytes,upload_bytes,uploads,needs,live_requests,ram_bytes,throttled_needs";
  for (const auto& c : system_columns_) header += "," + c;
  // The produce stage's columns only when a tile was produced: other runs' CSVs stay as they were.
  bool produced = false;
  for (const auto& r : frames_) produced |= r.produced > 0;
  if (produced) header += ",produced_tiles,produce_ms";
  header += "\n";
  std::fputs(header.c_str(), f.get());
  for (const auto& r : frames_) {
    const double bf = r.samples ? static_cast<double>(r.blurry) / r.samples : 0.0;
    const double md = r.samples ? r.deficit_sum / r.samples : 0.0;
    std::string line = fmt::format("{},{:.6f},{},{},{},{},{:.6f},{:.6f},{},{},{},{},{},{},{},{},{},{},{}", r.frame,
                                   r.t_s, r.clamp, r.bias, r.measured ? 1 : 0, r.samples, bf, md, r.pops,
                                   r.finest_needed, r.event ? 1 : 0, r.disk_bytes, r.decoded_bytes, r.upload_bytes,
                                   r.uploads, r.needs, r.live_requests, r.ram_bytes, r.throttled_needs);
    for (std::size_t i = 0; i < system_columns_.size(); ++i) line += fmt::format(",{}", r.system[i]);
    if (produced) line += fmt::format(",{},{:.6f}", r.produced, r.produce_ms);
    line += "\n";
    std::fputs(line.c_str(), f.get());
  }
  if (std::fflush(f.get()) != 0) throw InputError(path, "write failed");
}

}  // namespace vtsim
