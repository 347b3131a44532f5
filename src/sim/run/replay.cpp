#include "sim/run/replay.h"

#include <fmt/format.h>
#include <sys/resource.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <ctime>
#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>

#include "core/error.h"
#include "core/camera.h"
#include "sim/run/popin.h"
#include "sim/run/render_ahead.h"
#include "sim/view/scene.h"
#include "sim/trace/trace_resample.h"
#include "stream/system/clipmap_system.h"
#include "stream/system/i_system.h"
#include "stream/exec/sim_executor.h"
#include "stream/system/vt_system.h"

namespace vtsim {

std::unique_ptr<IScene> make_scene_from_config(const ReplayConfig& cfg) {
  SceneConfig sc;
  sc.kind = parse_scene_kind(cfg.scene);
  sc.texels_per_m = cfg.texels_per_m;
  sc.size_x_m = static_cast<double>(cfg.width) / cfg.texels_per_m;
  sc.size_y_m = static_cast<double>(cfg.height) / cfg.texels_per_m;
  sc.origin_x_m = cfg.origin_x_m;
  sc.origin_y_m = cfg.origin_y_m;
  if (sc.kind == SceneKind::heightfield) {
    sc.heightmap_path = cfg.scene_file;
    sc.height_scale_m = cfg.height_scale_m;
  }
  if (sc.kind == SceneKind::mesh) sc.obj_path = cfg.scene_file;
  auto scene = make_scene(sc);
  const TextureExtent e = scene->texture();
  if (e.width != cfg.width || e.height != cfg.height)
    throw InputError("config", fmt::format("field 'texture.width': the scene's texture is {}×{} texels, the config "
                                           "says {}×{} (texture size / texels_per_m must be exact)",
                                           e.width, e.height, cfg.width, cfg.height));
  return scene;
}

namespace {

// The parameters a replay config describes (validated config; extent from the scene).
VtSystemParams vt_system_params(const ReplayConfig& cfg, TextureExtent extent) {
  VtSystemParams p;
  p.extent = extent;
  p.page_size = cfg.tile_size;
  p.border = cfg.border;
  p.layers = static_cast<int>(cfg.layer_specs.size());
  p.page_bytes_all_layers = 0;
  for (const auto& L : cfg.layer_specs) p.page_bytes_all_layers += tile_decoded_bytes(cfg, L);
  p.pool_pages = static_cast<std::uint32_t>(cfg.vt_pool_pages);
  p.locked_levels = cfg.vt_locked_levels;
  p.prefetch_finer_levels = cfg.vt_prefetch_finer_levels;
  p.residency_window_frames = cfg.vt_residency_window_frames;
  p.thrash_frames = cfg.thrash_frames;
  return p;
}

}  // namespace

std::unique_ptr<IStreamingSystem> make_system(const ReplayConfig& cfg, const IScene& scene) {
  std::uint64_t all_layers = 0;
  for (const auto& L : cfg.layer_specs) all_layers += tile_decoded_bytes(cfg, L);
  if (cfg.system == "clipmap") {
    ClipmapSystemParams p;
    p.clipmap.extent = scene.texture();
    p.clipmap.tile_size = cfg.tile_size;
    p.clipmap.clipsize = cfg.clipsize;
    p.clipmap.layers = static_cast<int>(cfg.layer_specs.size());
    p.clipmap.update_threshold_tiles = cfg.update_threshold_tiles;
    p.clipmap.invalid_border_tiles = cfg.invalid_border_tiles;
    p.clipmap.filter_margin_texels = cfg.filter_margin_texels;
    p.texels_per_m = cfg.texels_per_m;
    p.origin_x_m = cfg.origin_x_m;
    p.origin_y_m = cfg.origin_y_m;
    p.tile_bytes_all_layers = all_layers;
    p.prefetch_lookahead_s = cfg.prefetch_lookahead_s;
    p.thrash_frames = cfg.thrash_frames;
    return std::make_unique<ClipmapSystem>(p);
  }
  if (cfg.system == "vt") return std::make_unique<VtSystem>(vt_system_params(cfg, scene.texture()));
  throw InputError("config", "field 'run.system': '" + cfg.system + "' is not available");
}

namespace {

double peak_rss_MB() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return static_cast<double>(ru.ru_maxrss) / 1024.0;  // Linux reports KiB
}

// CPU time of the calling thread, seconds: the frame loop's own work, without the feedback that
// render-ahead workers render.
double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// Angle between two orientations, radians (shortest arc).
double rotation_angle(const glm::dquat& a, const glm::dquat& b) {
  const double d = std::min(1.0, std::fabs(glm::dot(a, b)));
  return 2.0 * std::acos(d);
}

}  // namespace

ReplayResult run_replay(const ReplayConfig& cfg, const Trace& trace_in, const IScene& scene, const ReplayEnv& env) {
  const auto wall0 = std::chrono::steady_clock::now();
  const double cpu0 = thread_cpu_s();
  if (trace_in.poses.empty()) throw InputError(trace_in.name, "the trace has no poses");
  const Trace trace = cfg.fps > 0 ? resample(trace_in, cfg.fps) : trace_in;
  const int frames = static_cast<int>(trace.poses.size());
  if (frames == 0) throw InputError(trace_in.name, "the trace has no poses");

  auto system = make_system(cfg, scene);
  const int num_levels = system->num_levels();

  TileSizer sizer = env.sizer;
  if (!sizer) {
    std::vector<TileSizes> by_layer;
    for (const auto& L : cfg.layer_specs) by_layer.push_back({tile_disk_bytes(cfg, L), tile_decoded_bytes(cfg, L)});
    sizer = [by_layer](TileKey k) { return by_layer[k.layer() < by_layer.size() ? k.layer() : 0]; };
  }
  std::unique_ptr<SimExecutor> sim;
  IExecutor* exec = env.executor;
  if (!exec) {
    sim = std::make_unique<SimExecutor>(cfg.disk, cfg.decode, static_cast<std::size_t>(cfg.max_in_flight),
                                        cfg.faults);
    exec = sim.get();
  }
  PipelineConfig pc;
  pc.ram_bytes = static_cast<std::uint64_t>(cfg.ram_MiB * 1048576.0);
  pc.max_retries = cfg.max_retries;
  pc.retry_backoff_frames = cfg.retry_backoff_frames;
  pc.thrash_frames = cfg.thrash_frames;
  Pipeline pipe(pc, *exec, sizer);
  auto throttle = make_throttle_policy(cfg.throttle, cfg.throttle_params);
  if (!throttle) throw InputError("config", "field 'throttle.policy': unknown policy '" + cfg.throttle + "'");

  // Frame period and the upload budget the link allows per frame.
  const double t0 = trace.poses.front().t_s;
  const double period_s = cfg.fps > 0 ? 1.0 / cfg.fps
                                      : (frames > 1 ? (trace.poses.back().t_s - t0) / (frames - 1) : 1.0 / 60.0);
  const double duration_s = (trace.poses.back().t_s - t0) + period_s;
  UploadBudget budget{cfg.upload.bytes_per_frame, cfg.upload.tiles_per_frame};
  if (cfg.upload.link_MBps > 0) {
    const auto link_bytes = static_cast<std::uint64_t>(cfg.upload.link_MBps * 1e6 * period_s);
    budget.bytes = budget.bytes ? std::min(budget.bytes, link_bytes) : link_bytes;
  }
  // What the pipeline can bring into VRAM per second: its bottleneck (for throttling).
  double mean_disk = 0, mean_dec = 0;
  for (const auto& L : cfg.layer_specs) {
    mean_disk += static_cast<double>(tile_disk_bytes(cfg, L));
    mean_dec += static_cast<double>(tile_decoded_bytes(cfg, L));
  }
  mean_disk /= static_cast<double>(cfg.layer_specs.size());
  mean_dec /= static_cast<double>(cfg.layer_specs.size());
  double service = disk_throughput_Bps(cfg.disk, mean_disk) * (mean_dec / mean_disk);
  service = std::min(service, decode_throughput_Bps(cfg.decode, mean_dec));
  if (budget.bytes) service = std::min(service, static_cast<double>(budget.bytes) / period_s);
  if (budget.tiles) service = std::min(service, budget.tiles * mean_dec / period_s);
  if (!std::isfinite(service)) service = 0.0;  // unlimited

  ViewParams vp;
  vp.divisor = cfg.divisor;
  vp.lod_bias = static_cast<float>(cfg.lod_bias);
  vp.anisotropic = cfg.anisotropic;
  vp.max_aniso = static_cast<float>(cfg.max_aniso);
  vp.near_m = cfg.near_m;
  vp.far_m = cfg.far_m;
  ViewParams pp = vp;
  const bool separate_popin = cfg.popin_divisor > 0 && cfg.popin_divisor != cfg.divisor;
  if (separate_popin) pp.divisor = cfg.popin_divisor;

  // Feedback in run-length form: spans of one tile at their level, so a system that resolves spans
  // (the clipmap) works per span; others also get the per-sample buffer.
  SpanBuffer fb, pb;
  fb.block_shift = pb.block_shift = std::bit_width(static_cast<unsigned>(cfg.tile_size)) - 1;
  fb.keep_samples = pb.keep_samples = !system->uses_spans();
  SpanLevels lv_before, lv_after;
  std::vector<Need> needs;
  std::vector<UploadItem> uploads;
  std::vector<std::uint64_t> missing;
  ReplayResult res;
  MetricsCollector& m = res.metrics;
  int clamp = 0;
  double bias = 0.0;
  int finest_needed = num_levels;
  bool in_turn = false;
  bool cut = true;  // the first frame has no predecessor: treat it as a cut
  std::uint64_t level_upload[TileKey::kMaxLevels] = {};
  auto last_progress = wall0;
  m.set_system_columns(system->frame_counter_names());

  // The frames that render feedback: every feedback_every-th, unless its pose equals the last
  // rendered one (position, orientation, field of view), whose buffers it then reuses.
  std::vector<int> render_frames;
  {
    const Pose* last = nullptr;
    for (int f = 0; f < frames; f += cfg.feedback_every) {
      const Pose& p = trace.poses[static_cast<std::size_t>(f)];
      if (last && p.pos_m == last->pos_m && p.q.w == last->q.w && p.q.x == last->q.x && p.q.y == last->q.y &&
          p.q.z == last->q.z && p.vfov_deg == last->vfov_deg)
        continue;
      render_frames.push_back(f);
      last = &p;
    }
  }
  // Render-ahead (render_ahead.h): the same buffers, rendered by workers; the real clock's cores
  // belong to its IO and decode threads unless the config asks.
  const int render_threads = RenderAhead::cap_threads(
      env.executor && cfg.render_threads < 0 ? 0 : RenderAhead::resolve_threads(cfg.render_threads),
      RenderAhead::slot_bytes(trace.image_width, trace.image_height, vp, separate_popin ? &pp : nullptr));
  const auto camera_of = [&](std::size_t j) {
    return make_camera(trace.poses[static_cast<std::size_t>(render_frames[j])], trace.image_width, trace.image_height);
  };
  std::unique_ptr<RenderAhead> ahead;
  if (render_threads > 0 && !render_frames.empty())
    ahead = std::make_unique<RenderAhead>(scene, render_frames.size(), camera_of, vp, separate_popin ? &pp : nullptr,
                                          fb.block_shift, fb.keep_samples, render_threads);
  // Paced (the real clock): the first view is rendered before frame 0 starts. A renderer's first
  // call sets itself up (the town's per-triangle scratch, ~2 MB of memory touched for the first
  // time, page faults at ~13 µs a page on a paravirtualised VM): 8 ms of frame 0, which held back
  // its requests by two frames at --speed 4 (docs/real-engine.md §7a). A game has done that before
  // it streams, and the simulated clock gives frame work no time. Render-ahead workers (off by
  // default in the real clock) render the first frames, one each, before frame 0.
  if (env.pace && !render_frames.empty()) {
    if (ahead) {
      ahead->wait_rendered(static_cast<std::size_t>(render_threads));
    } else {
      const Camera cam = camera_of(0);
      fb.keep_samples = pb.keep_samples = !system->uses_spans() || system->wants_samples();  // as frame 0 will
      scene.render_spans(cam, vp, fb);
      if (separate_popin) scene.render_spans(cam, pp, pb);
    }
  }
  SpanBuffer* fbp = &fb;  // this frame's feedback and pop-in buffers
  SpanBuffer* pbp = &pb;
  std::size_t next_cam = 0;
  for (int f = 0; f < frames; ++f) {
    const Pose& pose = trace.poses[static_cast<std::size_t>(f)];
    const Ticks target = seconds_to_ticks(pose.t_s - t0);
    const Ticks now = env.pace ? env.pace(f, target) : target;
    const PipelineCounters c0 = pipe.counters();
    pipe.begin_frame(f, now);

    // The view: this frame's feedback (rendered here or ahead), else the last rendered one stands in.
    const bool render = f % cfg.feedback_every == 0;
    if (next_cam < render_frames.size() && render_frames[next_cam] == f) {
      // Shade samples in the render (not afterwards, from the spans) while the system reads them.
      const bool keep = !system->uses_spans() || system->wants_samples();
      if (keep != fb.keep_samples) {
        fb.keep_samples = pb.keep_samples = keep;
        if (ahead) ahead->set_keep_samples(keep);
      }
      if (ahead) {
        RenderAhead::Buffers& b = ahead->next();
        fbp = &b.feedback;
        pbp = &b.popin;
      } else {
        const Camera cam = camera_of(next_cam);
        scene.render_spans(cam, vp, fb);
        if (separate_popin) scene.render_spans(cam, pp, pb);
      }
      ++next_cam;
      finest_needed = finest_level(*fbp, num_levels);
    }
    // Motion: cuts, fast turns, velocity (for look-ahead).
    FrameRow row;
    row.frame = f;
    row.t_s = pose.t_s - t0;
    glm::dvec3 vel(0.0);
    if (f > 0) {
      const Pose& prev = trace.poses[static_cast<std::size_t>(f - 1)];
      const double dt = pose.t_s - prev.t_s;
      const glm::dvec3 d = pose.pos_m - prev.pos_m;
      cut = glm::length(d) > cfg.cut_m;
      const double ang = dt > 0 ? rotation_angle(prev.q, pose.q) / dt * 180.0 / 3.14159265358979323846 : 0.0;
      const bool turn = ang > cfg.turn_deg_per_s;
      row.event = cut || (turn && !in_turn);
      in_turn = turn;
      if (!cut && dt > 0) vel = d / dt;
    }

    if (system->wants_samples()) materialise_samples(*fbp);
    SystemFrame sf{f, now, &pose, vel, fbp->has_samples ? &fbp->view : nullptr, finest_needed, fbp};
    system->begin_frame(sf);
    system->missing_bytes_by_level(missing);
    ThrottleInput ti;
    ti.frame = f;
    ti.now = now;
    ti.frame_period_s = period_s;
    ti.num_levels = num_levels;
    ti.finest_needed = finest_needed;
    ti.coarsest_clamp = system->coarsest_clamp();
    ti.missing_bytes_by_level = missing;
    ti.service_Bps = service;
    ti.discontinuity = cut;
    ti.pool_occupancy = system->pool_occupancy();
    ti.pool_pressure = system->pool_pressure();
    system->pool_demand(ti.pool_demand_by_level, ti.pool_slots);
    const ThrottleDecision dec = throttle->update(ti);
    if (dec.clamp != clamp || dec.bias != bias)
      m.add_throttle_change({f, row.t_s, clamp, dec.clamp, dec.bias, dec.reason});
    clamp = dec.clamp;
    bias = dec.bias;
    system->apply_throttle(dec);

    needs.clear();
    system->emit_needs(needs);
    pipe.set_needs(needs);
    pipe.dispatch();

    uploads.clear();
    pipe.take_uploads(budget, uploads);
    const SpanBuffer& mb = separate_popin ? *pbp : *fbp;
    if (render && !uploads.empty()) {
      system->set_mark_sampled(false);
      resident_levels(mb, *system, lv_before);
    }
    for (const UploadItem& u : uploads) {
      if (!system->commit(u.key, f)) continue;
      TileLatency lat;
      lat.total = now - u.needed_time;
      lat.frames = f - u.needed_frame;
      lat.queue = u.queue_ticks;
      lat.io = u.io_ticks;
      lat.decode_wait = u.decode_wait_ticks;
      lat.decode = u.decode_ticks;
      lat.upload_wait = u.ram_ticks;
      lat.upload = transfer_ticks(u.bytes, cfg.upload.link_MBps * 1e6);
      lat.level = static_cast<std::uint8_t>(u.key.level());
      lat.ram_hit = u.ram_hit;
      m.add_latency(lat);
      level_upload[u.key.level()] += u.bytes;
      row.upload_bytes += u.bytes;
      ++row.uploads;
      if (env.on_upload) env.on_upload(u, system->vram_slot(u.key));
    }
    if (render) {
      system->set_mark_sampled(true);
      resident_levels(mb, *system, lv_after);
      const PopinFrame pf = popin_stats(mb, lv_after, uploads.empty() ? nullptr : &lv_before, num_levels);
      row.measured = true;
      row.samples = static_cast<std::uint32_t>(pf.samples);
      row.blurry = static_cast<std::uint32_t>(pf.blurry);
      row.deficit_sum = pf.mean_deficit * static_cast<double>(pf.samples);
      row.pops = static_cast<std::uint32_t>(pf.visible_pops);
    }
    const PipelineCounters& c1 = pipe.counters();
    row.clamp = clamp;
    row.bias = bias;
    row.finest_needed = finest_needed;
    row.disk_bytes = c1.disk_bytes - c0.disk_bytes;
    row.decoded_bytes = c1.decoded_bytes - c0.decoded_bytes;
    row.needs = static_cast<std::uint32_t>(needs.size());
    row.live_requests = static_cast<std::uint32_t>(pipe.live_requests());
    row.ram_bytes = pipe.ram_bytes_used();
    row.throttled_needs = system->throttled_needs();
    system->frame_counters(row.system);
    m.add_frame(row);

    if (env.progress) {
      const auto t = std::chrono::steady_clock::now();
      if (t - last_progress > std::chrono::seconds(1)) {
        env.progress(f, frames);
        last_progress = t;
      }
    }
  }
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  const double loop_cpu_s = thread_cpu_s() - cpu0;

  const PipelineCounters& c = pipe.counters();
  for (int l = 0; l < num_levels; ++l) m.add_level_bytes(l, c.disk_bytes_by_level[l], level_upload[l]);
  const auto MBps = [&](std::uint64_t bytes) { return static_cast<double>(bytes) / duration_s / 1e6; };
  nlohmann::json& s = res.summary;
  s["vtsim_version"] = VTSIM_VERSION;
  s["system"] = cfg.system;
  s["clock"] = env.clock_name;
  s["trace"] = {{"name", trace.name}, {"frames", frames}, {"duration_s", duration_s}, {"fps", 1.0 / period_s},
                {"image", {trace.image_width, trace.image_height}}};
  s["bandwidth"] = {
      {"disk_read_MBps", MBps(c.disk_bytes)},
      {"decoded_MBps", MBps(c.decoded_bytes)},
      {"upload_MBps", MBps(c.upload_bytes)},
      {"prefetch_read_MBps", MBps(c.prefetch_disk_bytes)},
      {"disk_read_bytes", c.disk_bytes},
      {"decoded_bytes", c.decoded_bytes},
      {"upload_bytes", c.upload_bytes},
      {"prefetch_read_bytes", c.prefetch_disk_bytes},
      {"disk_reads", c.disk_reads},
      {"uploads", c.uploads},
      {"upload_bytes_per_frame", m.upload_per_frame_json()["bytes"]},
      {"upload_tiles_per_frame", m.upload_per_frame_json()["tiles"]},
      {"per_level", m.per_level_json(duration_s)},
      {"wasted", {{"read_bytes_cancelled_after_io", c.wasted_read_bytes},
                  {"uploaded_bytes_never_sampled", system->evicted_unsampled_bytes()},
                  {"cancelled_before_io", c.cancelled_queued},
                  {"cancelled_after_io", c.cancelled_after_read},
                  {"dropped_before_upload", c.dropped_before_upload}}}};
  s["latency_ms"] = m.latency_json();
  s["popin"] = m.popin_json(cfg.sharp_margin);
  const double lookups = static_cast<double>(c.ram_hits + c.ram_misses);
  s["cache"] = {{"ram_hit_ratio", lookups > 0 ? static_cast<double>(c.ram_hits) / lookups : 0.0},
                {"ram_hits", c.ram_hits},
                {"ram_misses", c.ram_misses},
                {"ram_evictions", c.ram_evictions},
                {"ram_evicted_bytes", c.ram_evicted_bytes},
                {"ram_thrash", c.ram_thrash},
                {"prefetch_requests", c.prefetch_requests},
                {"prefetch_hits", c.prefetch_hits},
                {"vram_evictions", system->vram_evictions()},
                {"vram_thrash", system->vram_thrash()},
                {"requests", c.requests},
                {"needs", c.needs}};
  s["throttle"] = m.throttle_json();
  s["throttle"]["policy"] = cfg.throttle;
  s["faults"] = {{"faults", c.faults},
                 {"retries", c.retries},
                 {"failed_tiles", c.failed_tiles},
                 {"io_error", c.fault_by_kind[static_cast<int>(Fault::io_error)]},
                 {"short_read", c.fault_by_kind[static_cast<int>(Fault::short_read)]},
                 {"checksum", c.fault_by_kind[static_cast<int>(Fault::checksum)]},
                 {"decode_error", c.fault_by_kind[static_cast<int>(Fault::decode_error)]},
                 {"bad_record", c.fault_by_kind[static_cast<int>(Fault::bad_record)]}};
  s[cfg.system] = system->stats_json();
  if (env.on_finish) env.on_finish(*system);
  s["run"] = {{"wall_s", wall_s},
              {"render_threads", render_threads},
              {"loop_cpu_s", loop_cpu_s},
              {"frames_per_s", wall_s > 0 ? frames / wall_s : 0.0},
              {"x_realtime", wall_s > 0 ? duration_s / wall_s : 0.0},
              {"peak_rss_MB", peak_rss_MB()}};
  return res;
}

std::string format_summary(const nlohmann::json& s) {
  const auto& b = s["bandwidth"];
  const auto& l = s["latency_ms"];
  const auto& p = s["popin"];
  const auto& c = s["cache"];
  const auto& t = s["throttle"];
  const auto& r = s["run"];
  std::string out;
  out += fmt::format("{} replay ({} clock) of '{}': {} frames, {:.1f} s\n", s["system"].get<std::string>(),
                     s["clock"].get<std::string>(), s["trace"]["name"].get<std::string>(), s["trace"]["frames"].get<int>(),
                     s["trace"]["duration_s"].get<double>());
  out += fmt::format("  bandwidth   disk {:.2f} MB/s, decoded {:.2f} MB/s, upload {:.2f} MB/s (p99 {:.0f} B/frame)\n",
                     b["disk_read_MBps"].get<double>(), b["decoded_MBps"].get<double>(), b["upload_MBps"].get<double>(),
                     b["upload_bytes_per_frame"]["p99"].get<double>());
  out += fmt::format("  latency     p50 {:.1f} ms, p95 {:.1f} ms, p99 {:.1f} ms, max {:.1f} ms ({} tiles)\n",
                     l["p50"].get<double>(), l["p95"].get<double>(), l["p99"].get<double>(), l["max"].get<double>(),
                     l["tiles"].get<std::size_t>());
  out += fmt::format("  pop-in      blurry {:.2f}% mean (p99 {:.2f}%), mean deficit {:.3f} levels, {} visible pops\n",
                     100.0 * p["blurry_fraction_mean"].get<double>(), 100.0 * p["blurry_fraction_p99"].get<double>(),
                     p["mean_deficit"].get<double>(), p["visible_pops"].get<std::uint64_t>());
  const auto& tts = p["time_to_sharp_s"];
  if (tts["events"].get<std::size_t>() > 0)
    out += fmt::format("  sharp again {:.2f} s mean, {:.2f} s max after {} cuts/turns ({} never)\n", tts["mean"].get<double>(),
                       tts["max"].get<double>(), tts["events"].get<std::size_t>(), tts["never_sharp"].get<std::size_t>());
  out += fmt::format("  cache       RAM hit ratio {:.1f}%, {} RAM evictions, {} VRAM evictions\n",
                     100.0 * c["ram_hit_ratio"].get<double>(), c["ram_evictions"].get<std::uint64_t>(),
                     c["vram_evictions"].get<std::uint64_t>());
  if (s.contains("vt") && s["vt"].contains("pool")) {
    const auto& v = s["vt"];
    out += fmt::format("  vt          pool {} pages ({:.0f}% in use, mean), {} evictions, {} rescues, pressure max {:.2f}, "
                       "bias max {:.2f}; page table {} texels rewritten (baked)\n",
                       v["pool_pages"].get<std::uint64_t>(), 100.0 * v["per_frame"]["pool_occupancy"]["mean"].get<double>(),
                       v["pool"]["evictions"].get<std::uint64_t>(), v["pool"]["rescues"].get<std::uint64_t>(),
                       v["per_frame"]["pool_pressure"]["max"].get<double>(), v["per_frame"]["bias"]["max"].get<double>(),
                       v["page_table"]["texels_written_baked"].get<std::uint64_t>());
  }
  out += fmt::format("  throttle    {} frames throttled, max clamp {}, {} changes ({})\n", t["frames_throttled"].get<std::size_t>(),
                     t["max_clamp"].get<int>(), t["changes"].get<std::size_t>(), t["policy"].get<std::string>());
  if (s["faults"]["faults"].get<std::uint64_t>() > 0)
    out += fmt::format("  faults      {} faults, {} retries, {} tiles failed\n", s["faults"]["faults"].get<std::uint64_t>(),
                       s["faults"]["retries"].get<std::uint64_t>(), s["faults"]["failed_tiles"].get<std::uint64_t>());
  if (s.contains("real_clock")) {
    const auto& rc = s["real_clock"];
    out += fmt::format("  real clock  {} IO threads ({}), {} decode workers; start-up {:.2f} s; {} late frames (max {:.1f} ms); "
                       "VRAM arena: {:.1f} MB copied in {:.1f} ms\n",
                       rc["io_threads"].get<int>(), rc["o_direct"].get<bool>() ? "O_DIRECT" : "page cache",
                       rc["decode_workers"].get<int>(), rc.value("startup_s", 0.0), rc["late_frames"].get<std::uint64_t>(),
                       rc["max_late_ms"].get<double>(),
                       static_cast<double>(rc["vram_arena"]["bytes"].get<std::uint64_t>()) / 1e6,
                       rc["vram_arena"]["copy_ms"].get<double>());
  }
  out += fmt::format("  run         {:.2f} s wall, {:.0f} frames/s, {:.0f}x real time, peak {:.0f} MB", r["wall_s"].get<double>(),
                     r["frames_per_s"].get<double>(), r["x_realtime"].get<double>(), r["peak_rss_MB"].get<double>());
  if (r.contains("render_threads") && r["render_threads"].get<int>() > 0)
    out += fmt::format("; feedback on {} render threads, the loop's own CPU {:.2f} s", r["render_threads"].get<int>(),
                       r["loop_cpu_s"].get<double>());
  out += "\n";
  return out;
}

}  // namespace vtsim
