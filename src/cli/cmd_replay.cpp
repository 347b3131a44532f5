// vtsim replay: run a camera trace through a streaming system and report latency, pop-in and
// bandwidth (docs/architecture.md, docs/metrics.md); vtsim config: print every config key with its default and why.
#include <fmt/format.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <optional>

#include "cli/commands.h"
#include "core/error.h"
#include "sim/run/real_replay.h"
#include "sim/run/replay.h"
#include "sim/run/report_html.h"
#include "sim/view/scene.h"
#include "sim/view/scene_town.h"
#include "sim/trace/trace_import.h"
#include "stream/store/tile_store.h"

namespace vtsim::cli {

namespace {

struct ReplayArgs {
  std::string trace;
  std::string config;
  std::vector<std::string> sets;
  std::string system;
  std::string clock = "sim";
  std::string store;
  double speed = 1.0;
  std::string summary, frames, report;
  bool print_config = false, quiet = false, json = false, progress = false;
};

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw InputError(path, "cannot open for writing");
  out << text;
  if (!out.flush()) throw InputError(path, "write failed");
}

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
  const double x1 = cfg.origin_x_m + static_cast<double>(cfg.width) / cfg.texels_per_m;
  const double y1 = cfg.origin_y_m + static_cast<double>(cfg.height) / cfg.texels_per_m;
  std::string where = fmt::format("the texture covers x {:.1f}..{:.1f} m, y {:.1f}..{:.1f} m", cfg.origin_x_m, x1,
                                  cfg.origin_y_m, y1);
  if (cfg.scene == "town") {  // the town's layout is fixed (SceneConfig's defaults) from the texture's origin
    const double S = town_size_m(SceneConfig{});
    where = fmt::format("the town covers x {:.1f}..{:.1f} m, y {:.1f}..{:.1f} m (a walk in it: `vtsim trace gen walk "
                        "--start 30,8`)",
                        cfg.origin_x_m, cfg.origin_x_m + S, cfg.origin_y_m, cfg.origin_y_m + S);
  }
  return fmt::format("no frame saw a textured surface (0 samples in {} measured frames): the trace starts at "
                     "({:.1f}, {:.1f}, {:.1f}) m and {} (texture.origin_x_m, texture.origin_y_m, "
                     "texture.texels_per_m; docs/traces.md)",
                     measured, p.x, p.y, p.z, where);
}

}  // namespace

void run_replay_command(const ReplayArgs& a) {
  ReplayConfig cfg = load_replay_config(a.config, a.sets, a.system);
  if (a.print_config) {
    fmt::print("{}", replay_config_table().dump(cfg));
    return;
  }
  if (a.trace.empty()) throw InputError("--trace", "a trace file is required (see `vtsim trace gen --help`)");
  if (a.clock != "sim" && a.clock != "real")
    throw InputError("--clock", "'" + a.clock + "' is not one of: sim (device models), real (threads and files)");
  if (a.clock == "real" && a.store.empty())
    throw InputError("--store", "the real clock reads a tile store: give --store S (make one with `vtsim store gen`)");
  Trace trace = load_any_trace(a.trace);
  apply_speed(cfg, trace, a.speed);
  std::optional<TileStore> store;
  if (!a.store.empty()) {
    store.emplace(TileStore::open(a.store));
    for (const std::string& note : bind_store_texture(cfg, *store))
      if (!a.quiet) fmt::print(stderr, "vtsim: {}\n", note);
  }
  auto scene = make_scene_from_config(cfg);
  std::function<void(int, int)> progress;
  const bool tty = isatty(fileno(stderr)) != 0;
  if ((a.progress || tty) && !a.quiet)
    progress = [](int f, int n) { fmt::print(stderr, "\rframe {}/{} ({:.0f}%)", f, n, 100.0 * f / n); };
  ReplayResult r;
  if (a.clock == "real") {
    RealRun run = run_real_replay(cfg, trace, *scene, *store, RealClockOptions{progress});
    r = std::move(run.result);
    const std::string warning = r.summary["real_clock"]["o_direct_warning"].get<std::string>();
    if (!warning.empty() && !a.quiet) fmt::print(stderr, "vtsim: warning: {}\n", warning);
  } else {
    ReplayEnv env;
    env.progress = progress;
    if (store) env.sizer = store_sizer(*store);
    r = run_replay(cfg, trace, *scene, env);
  }
  if (a.speed != 1.0) r.summary["trace"]["speed"] = a.speed;
  if (progress) fmt::print(stderr, "\r{:40}\r", "");
  if (const std::string blind = blind_replay_warning(r.metrics, trace, cfg); !blind.empty() && !a.quiet)
    fmt::print(stderr, "vtsim: warning: {}\n", blind);
  if (!a.summary.empty()) write_text(a.summary, r.summary.dump(2) + "\n");
  if (!a.frames.empty()) r.metrics.write_frames_csv(a.frames);
  if (!a.report.empty()) write_text(a.report, html_report(r.summary, r.metrics));
  if (a.json) fmt::print("{}\n", r.summary.dump(2));
  else if (!a.quiet) fmt::print("{}", format_summary(r.summary));
}

void register_replay_commands(CLI::App& app) {
  auto a = std::make_shared<ReplayArgs>();
  auto* c = app.add_subcommand("replay", "Replay a camera trace through a streaming system; print and write metrics");
  c->add_option("--trace,-t", a->trace, "camera trace (native CSV, or TUM / EuRoC / KITTI, see docs/traces.md)");
  c->add_option("--config,-c", a->config, "TOML config file (docs/config.md)");
  c->add_option("--set", a->sets, "override one config key: --set upload.tiles_per_frame=8 (repeatable)");
  c->add_option("--system", a->system, "clipmap | vt (overrides run.system)");
  c->add_option("--clock", a->clock, "sim (device models, deterministic) | real (IO and decode threads on --store, wall-clock pacing)")
      ->capture_default_str();
  c->add_option("--store", a->store,
                "tile store (.vts): the texture and every tile's disk bytes come from it (both clocks); required by --clock real");
  c->add_option("--speed", a->speed, "play the trace this many times faster (both clocks)")->capture_default_str();
  c->add_option("--summary", a->summary, "write the summary JSON here");
  c->add_option("--frames", a->frames, "write one CSV row per frame here");
  c->add_option("--report", a->report, "write an HTML report with charts here");
  c->add_flag("--json", a->json, "print the summary JSON instead of the human summary");
  c->add_flag("--quiet,-q", a->quiet, "print nothing (files are still written)");
  c->add_flag("--progress", a->progress, "show progress even when stderr is not a terminal");
  c->add_flag("--print-config", a->print_config, "print the effective config (every key, value and why) and exit");
  c->callback([a] { run_replay_command(*a); });

  auto* cc = app.add_subcommand("config", "Print every config key with its default value and why");
  auto markdown = std::make_shared<bool>(false);
  cc->add_flag("--markdown", *markdown, "as the Markdown table of docs/config.md");
  cc->callback([markdown] {
    if (*markdown) fmt::print("{}", replay_config_table().markdown(ReplayConfig{}));
    else fmt::print("{}", replay_config_table().dump(ReplayConfig{}));
  });
}

}  // namespace vtsim::cli
