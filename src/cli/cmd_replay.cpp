// vtsim replay: run a camera trace through a streaming system and report latency, pop-in and
// bandwidth (docs/architecture.md, docs/metrics.md); vtsim config: print every config key with its default and why.
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <limits>
#include <optional>

#include "cli/cli_io.h"
#include "cli/commands.h"
#include "cli/trace_load.h"
#include "core/error.h"
#include "sim/run/real_replay.h"
#include "sim/run/replay.h"
#include "sim/run/systems.h"
#include "sim/report/report_html.h"
#include "sim/report/waterfall.h"
#include "sim/run/timeline.h"
#include "sim/view/scene.h"
#include "sim/run/feedback_replay.h"
#include "sim/trace/trace_import.h"
#include "stream/store/tile_store.h"
#include "stream/system/vt_system.h"

namespace vtsim::cli {

namespace {

struct ReplayArgs {
  std::string trace;
  std::vector<std::string> configs;
  std::vector<std::string> sets;
  std::string system;
  std::string clock = "sim";
  std::string store;
  double speed = 1.0;
  std::string summary, frames, report;
  std::string produce_samples;  // the terrain in the real clock: each composed tile's work and time (CSV)
  bool print_config = false, quiet = false, json = false, progress = false, opt = false;
  bool allow_repairs = false;
  std::string feedback, record_feedback;  // docs/feedback.md: replay from / record a feedback trace
  std::string timeline, timeline_frames;  // docs/metrics.md, "A tile's life on the timeline"
  double timeline_max_MB = 100.0;
  int waterfall_frame = -1;  // the report's waterfall of a chosen frame
};

// A replay whose camera never sees a textured surface measures nothing, and its summary looks
// like a perfect run (no pop-in, no bandwidth). Usually the trace was made for another texture
// placement or scene: say where the camera and the texture are. Empty when some frame saw one.
std::string blind_replay_warning(const MetricsCollector& m, const Trace& trace, const ReplayConfig& cfg) {
  std::size_t measured = 0;
  for (const FrameRow& f : m.frames()) {
    if (f.samples > 0) return {};
    measured += f.measured;
  }
  if (measured == 0 || trace.poses.empty()) return {};
  const glm::dvec3 p = trace.poses.front().pos_m;
  const TextureConfig& tx = cfg.texture;
  const double x1 = tx.origin_x_m + static_cast<double>(tx.width) / tx.texels_per_m;
  const double y1 = tx.origin_y_m + static_cast<double>(tx.height) / tx.texels_per_m;
  std::string where = fmt::format("the texture covers x {:.1f}..{:.1f} m, y {:.1f}..{:.1f} m", tx.origin_x_m, x1,
                                  tx.origin_y_m, y1);
  if (const SceneInfo* scene = scenes().find(cfg.scene.kind); scene && scene->where)  // a fixed layout (the town)
    where = scene->where(tx.origin_x_m, tx.origin_y_m);
  return fmt::format("no frame saw a textured surface (0 samples in {} measured frames): the trace starts at "
                     "({:.1f}, {:.1f}, {:.1f}) m and {} (texture.origin_x_m, texture.origin_y_m, "
                     "texture.texels_per_m; docs/traces.md)",
                     measured, p.x, p.y, p.z, where);
}

// A short human summary of a result.
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
  if (l.contains("served_fraction") && l["served_fraction"].is_number()) {  // every request, served or not
    const auto ms = [](const nlohmann::json& v) { return v.is_number() ? fmt::format("{:.1f} ms", v.get<double>()) : std::string("never"); };
    out += fmt::format("  served      {:.1f}% of {} requests ({} never served: waited p95 {:.1f} ms); all requests p50 {}, p95 {}\n",
                       100.0 * l["served_fraction"].get<double>(), l["requests"].get<std::size_t>(),
                       l["censored"]["count"].get<std::size_t>(), l["censored"]["wait_ms"]["p95"].get<double>(), ms(l["km"]["p50"]),
                       ms(l["km"]["p95"]));
  }
  out += fmt::format("  pop-in      blurry {:.2f}% mean (p99 {:.2f}%), mean deficit {:.3f} levels, {} visible pops\n",
                     100.0 * p["blurry_fraction_mean"].get<double>(), 100.0 * p["blurry_fraction_p99"].get<double>(),
                     p["mean_deficit"].get<double>(), p["visible_pops"].get<std::uint64_t>());
  const auto& tts = p["time_to_sharp_s"];
  if (tts["events"].get<std::size_t>() > 0 && tts["mean"].is_number())
    out += fmt::format("  sharp again {:.2f} s mean, {:.2f} s max after {} cuts/turns ({} never)\n", tts["mean"].get<double>(),
                       tts["max"].get<double>(), tts["events"].get<std::size_t>(), tts["never_sharp"].get<std::size_t>());
  else if (tts["events"].get<std::size_t>() > 0)
    out += fmt::format("  sharp again never after {} cuts/turns\n", tts["events"].get<std::size_t>());
  if (s.contains("startup")) {
    const auto& su = s["startup"];
    out += su["first_sharp_s"].is_number()
               ? fmt::format("  start-up    first sharp frame at {:.2f} s, after {} tiles", su["first_sharp_s"].get<double>(),
                             su["tiles_to_first_sharp"].get<std::size_t>())
               : std::string("  start-up    no frame was sharp");
    if (su["warmup_s"].get<double>() > 0)
      out += fmt::format("; warm-up {:.2f} s ({} frames, {} tiles) left out of the figures above",
                         su["warmup_s"].get<double>(), su["frames"].get<std::size_t>(), su["tiles"].get<std::size_t>());
    out += "\n";
  }
  out += fmt::format("  cache       RAM hit ratio {:.1f}%, {} RAM evictions, {} VRAM evictions\n",
                     100.0 * c["ram_hit_ratio"].get<double>(), c["ram_evictions"].get<std::uint64_t>(),
                     c["vram_evictions"].get<std::uint64_t>());
  if (s.contains(VtSystem::kName) && s[VtSystem::kName].contains("pool")) {
    const auto& v = s[VtSystem::kName];
    out += fmt::format("  vt          pool {} pages ({:.0f}% in use, mean), {} evictions, {} rescues, pressure max {:.2f}, "
                       "bias max {:.2f}; page table {} texels rewritten (baked)\n",
                       v["pool_pages"].get<std::uint64_t>(), 100.0 * v["per_frame"]["pool_occupancy"]["mean"].get<double>(),
                       v["pool"]["evictions"].get<std::uint64_t>(), v["pool"]["rescues"].get<std::uint64_t>(),
                       v["per_frame"]["pool_pressure"]["max"].get<double>(), v["per_frame"]["bias"]["max"].get<double>(),
                       v["page_table"]["texels_written_baked"].get<std::uint64_t>());
  }
  const auto bounds_line = [&](const char* level, const nlohmann::json& bd, std::uint64_t live, const char* unit) {
    const std::string opt = bd.contains("opt_misses")
                                ? fmt::format("Belady {}", bd["opt_misses"].get<std::uint64_t>())
                                : fmt::format("Belady-Size {} .. PFOO-L {}", bd["opt_misses_upper"].get<std::uint64_t>(),
                                              bd["opt_misses_lower"].get<std::uint64_t>());
    std::string knee;
    if (bd["mrc"]["knee"].is_object())
      knee = fmt::format("; LRU curve knee at {} {}", bd["mrc"]["knee"]["capacity"].get<std::uint64_t>(), unit);
    out += fmt::format("  {:<11} misses: {} live, offline {} {} / LRU {} / {} at {} {}{}\n", level, live,
                       bd["policy"].get<std::string>(), bd["policy_offline_misses"].get<std::uint64_t>(),
                       bd["lru_offline_misses"].get<std::uint64_t>(), opt, bd["capacity"].get<std::uint64_t>(), unit, knee);
  };
  if (s["cache"].contains("ram_bounds"))
    bounds_line("ram bounds", s["cache"]["ram_bounds"], s["cache"]["ram_misses"].get<std::uint64_t>(), "bytes");
  if (s.contains(VtSystem::kName) && s[VtSystem::kName].contains("pool") && s[VtSystem::kName]["pool"].contains("bounds"))
    bounds_line("pool bounds", s[VtSystem::kName]["pool"]["bounds"], s[VtSystem::kName]["pool"]["misses"].get<std::uint64_t>(), "pages");
  out += fmt::format("  throttle    {} frames throttled, max clamp {}, {} changes ({})\n", t["frames_throttled"].get<std::size_t>(),
                     t["max_clamp"].get<int>(), t["changes"].get<std::size_t>(), t["policy"].get<std::string>());
  if (s["faults"]["faults"].get<std::uint64_t>() > 0)
    out += fmt::format("  faults      {} faults, {} retries, {} tiles failed\n", s["faults"]["faults"].get<std::uint64_t>(),
                       s["faults"]["retries"].get<std::uint64_t>(), s["faults"]["failed_tiles"].get<std::uint64_t>());
  if (s.contains("real_clock")) {
    const auto& rc = s["real_clock"];
    if (rc.contains("producer")) {  // the terrain: production threads only (docs/produced.md, "The real clock")
      const auto& pr = rc["producer"];
      out += fmt::format("  real clock  {} production threads: {} tiles composed, {} brush mips served ({:.1f} MB); start-up {:.2f} s; "
                         "{} late frames (max {:.1f} ms); VRAM arena: {:.1f} MB copied in {:.1f} ms\n",
                         pr["produce_workers"].get<int>(), pr["tiles_composed"].get<std::uint64_t>(),
                         pr["brush_mips_served"].get<std::uint64_t>(),
                         static_cast<double>(pr["brush_bytes_served"].get<std::uint64_t>()) / 1e6, rc.value("startup_s", 0.0),
                         rc["late_frames"].get<std::uint64_t>(), rc["max_late_ms"].get<double>(),
                         static_cast<double>(rc["vram_arena"]["bytes"].get<std::uint64_t>()) / 1e6,
                         rc["vram_arena"]["copy_ms"].get<double>());
    } else {
      out += fmt::format("  real clock  {} IO threads ({}), {} decode workers; start-up {:.2f} s; {} late frames (max {:.1f} ms); "
                         "VRAM arena: {:.1f} MB copied in {:.1f} ms\n",
                         rc["io_threads"].get<int>(),
                         std::string(rc["o_direct"].get<bool>() ? "O_DIRECT" : "page cache") +
                             (rc.value("io_engine", std::string("psync")) == "io_uring"
                                  ? fmt::format(", io_uring depth {}", rc.value("io_queue_depth", 0))
                                  : std::string(", psync")),
                         rc["decode_workers"].get<int>(), rc.value("startup_s", 0.0), rc["late_frames"].get<std::uint64_t>(),
                         rc["max_late_ms"].get<double>(),
                         static_cast<double>(rc["vram_arena"]["bytes"].get<std::uint64_t>()) / 1e6,
                         rc["vram_arena"]["copy_ms"].get<double>());
    }
  }
  out += fmt::format("  run         {:.2f} s wall, {:.0f} frames/s, {:.0f}x real time, peak {:.0f} MB", r["wall_s"].get<double>(),
                     r["frames_per_s"].get<double>(), r["x_realtime"].get<double>(), r["peak_rss_MB"].get<double>());
  if (r.contains("render_threads") && r["render_threads"].get<int>() > 0)
    out += fmt::format("; feedback on {} render threads, the loop's own CPU {:.2f} s", r["render_threads"].get<int>(),
                       r["loop_cpu_s"].get<double>());
  out += "\n";
  return out;
}

// The real clock's warnings from its summary section: O_DIRECT refused, the io_uring fallback, and
// the tiles that failed after their retries (the first three named).
void warn_real_clock(const nlohmann::json& rc, const std::string& store) {
  const std::string warning = rc["o_direct_warning"].get<std::string>();
  if (!warning.empty()) warn(warning);
  if (const std::string w = rc.value("io_engine_warning", std::string()); !w.empty()) warn(w);
  if (const auto& failed = rc["failed_tiles"]; !failed.empty()) {
    std::string list;
    for (std::size_t i = 0; i < failed.size() && i < 3; ++i)
      list += fmt::format("{}layer {} level {} ({}, {}) {}", i ? ", " : "", failed[i]["layer"].get<int>(),
                          failed[i]["level"].get<int>(), failed[i]["x"].get<std::int64_t>(), failed[i]["y"].get<std::int64_t>(),
                          failed[i]["fault"].get<std::string>());
    const std::size_t n = failed.size() + rc["failed_tiles_not_listed"].get<std::size_t>();
    warn(fmt::format("{} tile{} failed after io.max_retries retries: {}{} (each with its reason in the summary's real_clock.failed_tiles; "
                     "`vtsim store verify {}` checks every tile)",
                     n, n == 1 ? "" : "s", list, n > 3 ? ", ..." : "", store));
  }
}

// --report: the replay report, with the waterfalls of the most blurry frame after the start-up fill
// (from the first sharp frame) and of --waterfall-frame when a timeline was recorded.
void write_replay_report(const ReplayArgs& a, const ReplayConfig& cfg, const ReplayResult& r, const TimelineRecorder* timeline) {
  ReportConfig shown;
  for (const auto& f : replay_config_table().fields()) shown.emplace_back(f.key, f.get(cfg));
  std::string waterfalls;
  if (timeline) {
    int from = 0;
    if (const auto& fs = r.summary["startup"]["first_sharp_s"]; fs.is_number())
      for (const FrameRow& row : r.metrics.frames())
        if (row.t_s >= fs.get<double>()) {
          from = row.frame;
          break;
        }
    const int worst = worst_frame(*timeline, from);
    if (worst >= 0) waterfalls += waterfall_svg(frame_waterfall(*timeline, worst, from > 0 ? "the most blurry after the start-up fill" : "the most blurry"));
    if (a.waterfall_frame >= 0) waterfalls += waterfall_svg(frame_waterfall(*timeline, a.waterfall_frame, "--waterfall-frame"));
  }
  write_output(a.report, html_report(r.summary, r.metrics, shown, waterfalls));
}

}  // namespace

void run_replay_command(const ReplayArgs& a) {
  std::vector<std::string> sets = a.sets;
  if (a.opt) sets.push_back("metrics.opt=true");
  const bool config_stdin = std::find(a.configs.begin(), a.configs.end(), "-") != a.configs.end();
  if (config_stdin && a.trace == "-") throw InputError("--config", "--config - and --trace - cannot both read stdin");
  ReplayConfig cfg = load_cli_config(a.configs, sets, a.system);
  if (a.print_config) {
    fmt::print("{}", replay_config_table().dump(cfg));
    return;
  }
  if (!a.feedback.empty() && !a.trace.empty()) throw InputError("--feedback", "replays a feedback trace instead of --trace: give one of them");
  if (!a.feedback.empty() && !a.record_feedback.empty()) throw InputError("--record-feedback", "records a camera replay's feedback: not with --feedback");
  if ((!a.feedback.empty() || !a.record_feedback.empty()) && a.clock != "sim")
    throw InputError(a.feedback.empty() ? "--record-feedback" : "--feedback", "feedback traces replay in the simulated clock (--clock sim)");
  if (!a.feedback.empty() && a.speed != 1.0)
    throw InputError("--speed", "a feedback trace replays at its own frame times (docs/feedback.md): not with --feedback");
  if (a.trace.empty() && a.feedback.empty())
    throw InputError("--trace", "a trace file is required (see `vtsim trace gen --help`), or --feedback FILE");
  // Every output checked before the work: a real-clock run is not thrown away for a typo.
  check_output("--summary", a.summary);
  check_output("--frames", a.frames);
  check_output("--report", a.report);
  check_output("--produce-samples", a.produce_samples);
  check_output("--record-feedback", a.record_feedback);
  check_output("--timeline", a.timeline);
  TimelineOptions tl_opt;
  if (!a.timeline_frames.empty()) {
    if (a.timeline.empty()) throw InputError("--timeline-frames", "limits --timeline FILE: give it too");
    parse_timeline_frames("--timeline-frames", a.timeline_frames, tl_opt);
  }
  if (!(a.timeline_max_MB > 0)) throw InputError("--timeline-max-MB", "must be > 0");
  tl_opt.max_bytes = static_cast<std::uint64_t>(a.timeline_max_MB * 1e6);
  if (!a.produce_samples.empty() && (a.clock != "real" || !produced_system(cfg)))
    throw InputError("--produce-samples", fmt::format("records the tiles the terrain's compositor makes in the real clock: needs --clock real "
                                                      "and run.system = \"terrain\" (here --clock {}, run.system = \"{}\")",
                                                      a.clock, cfg.run.system));
  int to_stdout = a.json ? 1 : 0;
  for (const std::string* o : {&a.summary, &a.frames, &a.report, &a.produce_samples}) to_stdout += *o == "-" ? 1 : 0;
  if (to_stdout > 1)
    throw InputError(a.json ? "--json" : "--summary/--frames/--report/--produce-samples",
                     "only one of --json, --summary -, --frames -, --report -, --produce-samples - can write to stdout");
  if (a.timeline == "-" && to_stdout++ > 0) throw InputError("--timeline", "- writes to stdout, which another output already takes");
  if (a.clock != "sim" && a.clock != "real")
    throw InputError("--clock", "'" + a.clock + "' is not one of: sim (device models), real (threads and files)");
  if (a.clock == "real") check_real_clock_system(cfg, !a.store.empty());  // the terrain: no store, a producer
  check_input("--store", a.store);
  if (!a.feedback.empty()) check_input("--feedback", a.feedback);
  Trace trace = a.feedback.empty() ? load_cli_trace(a.trace, a.allow_repairs) : Trace{};
  apply_speed(cfg, trace, a.speed);
  std::optional<TileStore> store;
  if (!a.store.empty()) {
    store.emplace(TileStore::open(a.store));
    for (const std::string& w : store->header().warnings) warn(w);
    for (const std::string& note : bind_store_texture(cfg, *store))
      if (!a.quiet) fmt::print(stderr, "vtsim: {}\n", note);  // information: -q hides it
  }
  std::unique_ptr<IScene> scene;
  if (a.feedback.empty()) {  // a feedback replay renders nothing
    scene = make_scene_from_config(cfg);
    for (const std::string& w : scene->load_warnings()) warn(w);
  }
  // The timeline's size bound, before the run (a feedback trace's frames are known once it is open:
  // its recorder checks the bound at each frame). The report's waterfalls read the same recorder
  // (without --timeline: every frame, nothing written, no bound).
  std::optional<TimelineRecorder> timeline;
  if (a.waterfall_frame >= 0 && a.report.empty()) throw InputError("--waterfall-frame", "adds a chart to --report FILE: give it too");
  const int plan_count = a.feedback.empty() && (!a.timeline.empty() || a.waterfall_frame >= 0) ? plan_frames(cfg, trace).frames : -1;
  if (a.waterfall_frame >= 0 && plan_count >= 0 && a.waterfall_frame >= plan_count)
    throw InputError("--waterfall-frame", fmt::format("frame {} is past the run's last frame, {}", a.waterfall_frame, plan_count - 1));
  if (!a.timeline.empty()) {
    if (plan_count >= 0) check_timeline_bound(cfg, plan_count, tl_opt);
    timeline.emplace(tl_opt);
  } else if (!a.report.empty()) {
    TimelineOptions unbounded;
    unbounded.max_bytes = std::numeric_limits<std::uint64_t>::max();
    timeline.emplace(unbounded);
  }
  std::function<void(int, int)> progress;
  const bool tty = isatty(fileno(stderr)) != 0;
  if ((a.progress || tty) && !a.quiet)
    progress = [tty, last = -1](int f, int n) mutable {  // a log gets a line each 10 %, never a "\r"
      if (tty) return fmt::print(stderr, "\rframe {}/{} ({:.0f}%)", f, n, 100.0 * f / n);
      const int tenth = n > 0 ? static_cast<int>(10.0 * f / n) : 10;
      if (tenth == last) return;
      last = tenth;
      fmt::print(stderr, "frame {}/{} ({:.0f}%)\n", f, n, 100.0 * f / n);
    };
  ReplayResult r;
  if (a.clock == "real") {
    RealClockOptions ro{progress};
    ro.record_produced_tiles = !a.produce_samples.empty();
    ro.timeline = timeline ? &*timeline : nullptr;
    RealRun run = store ? run_real_replay(cfg, trace, *scene, *store, ro) : run_real_replay(cfg, trace, *scene, ro);
    r = std::move(run.result);
    if (!a.produce_samples.empty()) write_output(a.produce_samples, produce::produced_tiles_csv(run.produced_tiles));
    warn_real_clock(r.summary["real_clock"], a.store);
  } else {
    ReplayEnv env;
    env.progress = progress;
    if (store) env.sizer = store_sizer(*store);
    env.timeline = timeline ? &*timeline : nullptr;
    std::optional<FeedbackRecorder> rec;
    if (!a.record_feedback.empty()) {
      rec.emplace(a.record_feedback, cfg);
      env.on_view = [&rec](const FramePlan& p, const FrameView& v) { (*rec)(p, v); };
    }
    r = a.feedback.empty() ? run_replay(cfg, trace, *scene, env) : run_feedback_replay(cfg, a.feedback, env);
    if (rec) {
      const std::uint64_t bytes = rec->finish();
      if (!a.quiet)
        fmt::print(stderr, "vtsim: feedback trace {}: {} frames, {} bytes ({:.0f} bytes a frame)\n", a.record_feedback, rec->frames(),
                   bytes, static_cast<double>(bytes) / static_cast<double>(std::max<std::uint64_t>(1, rec->frames())));
    }
  }
  if (a.speed != 1.0) r.summary["trace"]["speed"] = a.speed;
  if (progress && tty) fmt::print(stderr, "\r{:40}\r", "");
  if (a.feedback.empty())
    if (const std::string blind = blind_replay_warning(r.metrics, trace, cfg); !blind.empty()) warn(blind);
  if (timeline && !a.timeline.empty()) {
    const std::string json = timeline->json();  // throws over its bound: nothing written
    write_output(a.timeline, json);
    if (!a.quiet && a.timeline != "-")
      fmt::print(stderr, "vtsim: timeline {}: {} tile requests over {} frames, {} bytes ({:.0f} bytes a frame)\n", a.timeline,
                 timeline->lives().size(), timeline->frames().size(), json.size(),
                 static_cast<double>(json.size()) / static_cast<double>(std::max<std::size_t>(1, timeline->frames().size())));
  }
  if (!a.summary.empty()) write_output(a.summary, r.summary.dump(2) + "\n");
  if (!a.frames.empty()) write_output_via(a.frames, [&](const std::string& p) { r.metrics.write_frames_csv(p); });
  if (!a.report.empty()) write_replay_report(a, cfg, r, timeline ? &*timeline : nullptr);
  if (a.json) fmt::print("{}\n", r.summary.dump(2));
  else if (!a.quiet && to_stdout == 0) fmt::print("{}", format_summary(r.summary));
  else if (!a.quiet && !a.json) fmt::print(stderr, "{}", format_summary(r.summary));  // stdout carries a file
}

void register_replay_commands(CLI::App& app) {
  auto a = std::make_shared<ReplayArgs>();
  auto* c = app.add_subcommand("replay", "Replay a camera trace through a streaming system; print and write metrics");
  c->add_option("--trace,-t", a->trace, "camera trace (native CSV, or TUM / EuRoC / KITTI, see docs/traces.md; - for stdin)");
  c->add_option("--config,-c", a->configs, "TOML config file (docs/config.md; - for stdin); repeatable: files read in order, a later one overriding an earlier one's keys")->allow_extra_args(false);
  c->add_option("--set", a->sets, "override one config key: --set upload.tiles_per_frame=8 (repeatable)");
  c->add_option("--system", a->system, streaming_systems().names(" | ") + " (overrides run.system)");
  c->add_option("--clock", a->clock, "sim (device models, deterministic) | real (IO and decode threads on --store, or the terrain's production "
                "threads, wall-clock pacing)")
      ->capture_default_str();
  c->add_option("--store", a->store,
                "tile store (.vts): the texture and every tile's disk bytes come from it (both clocks); required by --clock real, except for run.system terrain (produced: no store)");
  c->add_option("--speed", a->speed, "play the trace this many times faster (both clocks)")->capture_default_str();
  c->add_option("--summary", a->summary, "write the summary JSON here (- for stdout)");
  c->add_option("--frames", a->frames, "write one CSV row per frame here (- for stdout)");
  c->add_option("--report", a->report, "write an HTML report with charts here (- for stdout)");
  c->add_option("--produce-samples", a->produce_samples,
                "the terrain in the real clock: write each composed tile's work and time here (CSV, for `vtsim calibrate --samples`)");
  c->add_option("--feedback", a->feedback,
                "replay the streaming side from this feedback trace instead of --trace: no render (docs/feedback.md)");
  c->add_option("--record-feedback", a->record_feedback,
                "write the feedback trace of this camera replay here (docs/feedback.md)");
  c->add_option("--timeline", a->timeline,
                "write every tile request's stages with their times here, as Chrome's Trace Event JSON (Perfetto, "
                "chrome://tracing; - for stdout; docs/metrics.md)");
  c->add_option("--timeline-frames", a->timeline_frames, "record the timeline of frames A to B only (A:B, 0-based, inclusive; A: to the end)");
  c->add_option("--timeline-max-MB", a->timeline_max_MB, "the timeline's size bound, MB: a larger one is refused before the run")
      ->capture_default_str();
  c->add_option("--waterfall-frame", a->waterfall_frame,
                "--report also shows the waterfall of this frame's tiles (0-based; the most blurry frame's is always shown)");
  c->add_flag("--json", a->json, "print the summary JSON instead of the human summary");
  c->add_flag("--quiet,-q", a->quiet, "print no information (files are still written; warnings still are: --werror makes them fail the run)");
  c->add_flag("--allow-repairs", a->allow_repairs, kAllowRepairsHelp);
  c->add_flag("--progress", a->progress, "show progress even when stderr is not a terminal");
  c->add_flag("--opt", a->opt, "also replay each cache level's recorded accesses offline: Belady's bound, the policy, LRU, "
                                 "the miss-ratio curve (= --set metrics.opt=true; docs/cache.md)");
  c->add_flag("--print-config", a->print_config, "print the effective config (every key, value and why) and exit");
  c->callback([a] { run_replay_command(*a); });

  auto* cc = app.add_subcommand("config", "Print every config key with its default value and why");
  auto markdown = std::make_shared<bool>(false);
  cc->add_flag("--markdown", *markdown, "as the Markdown reference of docs/config.md (keys, then every registry)");
  cc->callback([markdown] {
    if (*markdown) fmt::print("{}", config_reference_markdown());
    else fmt::print("{}", replay_config_table().dump(ReplayConfig{}));
  });
}

}  // namespace vtsim::cli
