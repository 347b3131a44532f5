// vtsim calibrate: measure this machine's disk and decode on a tile store and write a device
// profile (TOML config keys) that the simulated clock uses to predict the real one
// (docs/real-engine.md §5). With --produce: time the CPU compositor instead and write the
// [produce] keys (docs/produced.md, "Calibration").
#include <fmt/format.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>

#include "cli/cli_io.h"
#include "cli/commands.h"
#include "core/error.h"
#include "stream/exec/calibrate.h"
#include "stream/produce/produce_calibrate.h"
#include "stream/store/tile_store.h"

namespace vtsim::cli {

namespace {

struct CalibrateArgs {
  std::string store, out;
  int io_threads = 4, decode_workers = 2;
  std::string engine = "psync";  // io.engine the profile is for
  int queue_depth = 16;          // io.queue_depth (io_uring)
  double seconds = 0.4;
  bool buffered = false, quick = false, quiet = false, json = false, produce = false;
  int produce_workers = 2;
  double produce_texel_m = 1.0 / 1024;  // output texel the compositor is timed at (level 0 of the default terrain, VT Terrain Design's)
  std::vector<std::string> samples;      // produced-tiles CSVs of real-clock replays: fit to those instead of timing
  bool cpu_time = false;                 // with samples: fit their thread CPU time, not their wall time
  std::uint64_t seed = 1;
};

CalibrateProgress calibrate_progress(bool quiet, bool tty) {
  if (quiet) return {};
  return [tty](const std::string& s) {
    if (tty) fmt::print(stderr, "\r{:60}", s);
    else fmt::print(stderr, "{}\n", s);
  };
}

void run_calibrate_produce(const CalibrateArgs& a) {
  check_output("--output", a.out);
  if (a.json && a.out == "-") throw InputError("--output", "--json already prints to stdout: give a file or drop --json");
  if (a.produce_workers < 0) throw InputError("--produce-workers", fmt::format("{} (must be >= 0)", a.produce_workers));
  if (!(a.produce_texel_m > 0) || !(a.produce_texel_m <= 1e6))
    throw InputError("--produce-texel-m", fmt::format("{} (an output texel in metres, > 0)", a.produce_texel_m));
  produce::ProduceMeasureOptions o;
  o.seed = a.seed;
  o.m_per_texel = a.produce_texel_m;
  if (a.quick) {
    o.tiles = {64, 128};
    o.borders = {0, 4};
    o.layers = {1, 4, 8};
    o.decals = {0};
    o.repeats = 3;
    o.brush_side = 256;
  }
  const bool tty = isatty(fileno(stderr)) != 0;
  std::vector<produce::ProduceSample> samples;
  if (a.samples.empty()) {
    samples = produce::measure_compositor(o, calibrate_progress(a.quiet, tty));
    if (!a.quiet && tty) fmt::print(stderr, "\r{:60}\r", "");
  } else {
    // The replay's own tiles (docs/produced.md, "Calibrating from the replay's own tiles").
    for (const std::string& f : a.samples) {
      const std::vector<produce::ProducedTile> tiles = produce::read_produced_tiles_csv(f);
      if (tiles.empty()) throw InputError(f, "no tiles (the replay composed none: a longer trace, or one that moves)");
      const std::vector<produce::ProduceSample> s = produce::samples_from_tiles(tiles, a.cpu_time);
      samples.insert(samples.end(), s.begin(), s.end());
    }
  }
  ProduceModel base;
  base.workers = a.produce_workers;
  // A replay's tiles: least squares on the absolute error, so the model's sum is theirs (produce_calibrate.h).
  const produce::ProduceFit fit = produce::fit_produce_model(samples, base, a.samples.empty());
  const std::string toml = produce::produce_profile_toml(fit, samples);
  if (!a.out.empty()) write_output(a.out, toml);
  if (a.json) {
    nlohmann::json j;
    for (const auto& p : samples)
      j["compositor"].push_back({{"tile", p.tile}, {"border", p.border}, {"texels", p.texels}, {"layers", p.layers},
                                 {"decals", p.decals}, {"decal_texels", p.decal_texels}, {"us", p.ns / 1000}});
    j["profile"] = {{"produce.per_tile_us", fit.model.per_tile_us}, {"produce.per_texel_ns", fit.model.per_texel_ns},
                    {"produce.per_layer_texel_ns", fit.model.per_layer_texel_ns}, {"produce.per_decal_us", fit.model.per_decal_us},
                    {"produce.per_decal_texel_ns", fit.model.per_decal_texel_ns},
                    {"produce.workers", fit.model.workers}};
    j["source"] = a.samples.empty() ? "compositor" : "samples";
    j["measured_ms"] = fit.measured_ms;
    j["model_ms"] = fit.model_ms;
    j["median_rel_error"] = fit.median_rel_error;
    j["max_rel_error"] = fit.max_rel_error;
    j["notes"] = fit.notes;
    fmt::print("{}\n", j.dump(2));
  } else if (a.out.empty()) {
    fmt::print("{}", toml);
  } else if (a.out != "-" && !a.quiet) {
    fmt::print("{}", toml.substr(toml.find("[produce]")));
    fmt::print("wrote {}\n", a.out);
  }
}

void run_calibrate(const CalibrateArgs& a) {
  if (!a.samples.empty() && !a.store.empty())
    throw InputError("--samples", "fits the [produce] keys to a replay's composed tiles, not a store: drop --store");
  if (a.cpu_time && a.samples.empty()) throw InputError("--cpu-time", "applies to --samples (the compositor's own timing is CPU time already)");
  if (a.produce || !a.samples.empty()) {
    if (!a.store.empty()) throw InputError("--store", "--produce measures the compositor, not a store: give one or the other");
    return run_calibrate_produce(a);
  }
  if (a.store.empty()) throw InputError("--store", "required (the tile store to measure), unless --produce");
  check_output("--output", a.out);  // before the measurements, not after
  if (a.json && a.out == "-") throw InputError("--output", "--json already prints to stdout: give a file or drop --json");
  const TileStore store = TileStore::open(a.store);
  for (const std::string& w : store.header().warnings) warn(w);
  CalibrateOptions o;
  o.io_threads = a.io_threads;
  o.decode_workers = a.decode_workers;
  o.direct = !a.buffered;
  o.seconds_per_point = a.quick ? std::min(a.seconds, 0.1) : a.seconds;
  o.seed = a.seed;
  if (a.quick) o.concurrency = {1, a.io_threads};
  try {
    o.engine = io_engines().at(a.engine).engine;
  } catch (const std::invalid_argument& e) {
    throw InputError("--engine", e.what());
  }
  if (a.queue_depth < 1 || a.queue_depth > 1024) throw InputError("--queue-depth", fmt::format("{} is outside 1..1024", a.queue_depth));
  o.queue_depth = a.queue_depth;
  if (a.quick) o.depths = {1, a.queue_depth};
  const bool tty = isatty(fileno(stderr)) != 0;
  const Calibration c = calibrate(store, o, calibrate_progress(a.quiet, tty));
  if (!a.quiet && tty) fmt::print(stderr, "\r{:60}\r", "");
  if (!c.direct_warning.empty()) warn(c.direct_warning);
  if (!c.engine_warning.empty()) warn(c.engine_warning);
  const std::string toml = profile_toml(c, a.store);
  if (!a.out.empty()) write_output(a.out, toml);
  if (a.json) {
    nlohmann::json j;
    for (const auto& p : c.reads)
      j["reads"].push_back({{"bytes", p.bytes}, {"concurrency", p.concurrency}, {"reads", p.reads}, {"MBps", p.MBps},
                            {"depth", p.depth}, {"mean_us", p.mean_us}, {"p50_us", p.p50_us}, {"p95_us", p.p95_us}, {"p99_us", p.p99_us}});
    for (const auto& p : c.decodes)
      j["decode"].push_back({{"what", p.what}, {"workers", p.workers}, {"tiles", p.tiles}, {"us_per_tile", p.us_per_tile},
                             {"tiles_per_s", p.tiles_per_s}, {"decoded_MBps", p.decoded_MBps}});
    j["profile"] = {{"disk.latency_us", c.disk.latency_us}, {"disk.bandwidth_MBps", c.disk.bandwidth_MBps},
                    {"disk.channels", c.disk.channels}, {"disk.queue_depth", c.disk.queue_depth},
                    {"decode.per_tile_us", c.decode.per_tile_us},
                    {"decode.throughput_MBps", c.decode.throughput_MBps}, {"decode.workers", c.decode.workers},
                    {"io.threads", c.io_threads}, {"io.direct", c.direct}, {"io.engine", std::string(engine_name(c.engine))},
                    {"io.queue_depth", c.queue_depth}};
    j["notes"] = c.notes;
    fmt::print("{}\n", j.dump(2));
  } else if (a.out.empty()) {
    fmt::print("{}", toml);
  } else if (a.out == "-") {
    // written above
  } else if (!a.quiet) {
    fmt::print("{}", toml.substr(0, toml.find("\n[disk]")));
    fmt::print("\nwrote {}\n", a.out);
  }
}

}  // namespace

void register_calibrate_commands(CLI::App& app) {
  auto a = std::make_shared<CalibrateArgs>();
  auto* c = app.add_subcommand("calibrate",
                               "Measure read latency/bandwidth and decode speed on a tile store (or the compositor: --produce); write a device profile for the simulated clock");
  c->add_option("--store,-s", a->store, "tile store (.vts) to measure on (required unless --produce)");
  c->add_flag("--produce", a->produce, "time the CPU compositor on one thread and fit the [produce] keys instead (no store)");
  c->add_option("--produce-workers", a->produce_workers, "production workers the profile is for (produce.workers)")->capture_default_str();
  c->add_option("--produce-texel-m", a->produce_texel_m,
                "output texel the compositor is timed at, m (1/1024: the terrain's level 0; a coarser level's texel is 2^level times it)")
      ->capture_default_str();
  c->add_option("--samples", a->samples,
                "fit the [produce] keys to these real-clock replays' composed tiles (CSV from `vtsim replay --clock real "
                "--produce-samples`; repeatable) instead of timing the compositor; implies --produce");
  c->add_flag("--cpu-time", a->cpu_time, "with --samples: fit each tile's production-thread CPU time instead of its wall time");
  c->add_option("--output,-o", a->out, "write the profile (TOML config keys) here (- for stdout); default: print it");
  c->add_option("--io-threads", a->io_threads, "IO pool threads the profile is for (io.threads)")->capture_default_str();
  c->add_option("--engine", a->engine, "IO engine the profile is for (io.engine): psync | io_uring")->capture_default_str();
  c->add_option("--queue-depth", a->queue_depth, "io_uring: reads in flight per IO thread the profile is for (io.queue_depth)")
      ->capture_default_str();
  c->add_option("--decode-workers", a->decode_workers, "decode workers the profile is for (decode.workers)")->capture_default_str();
  c->add_option("--seconds", a->seconds, "measuring time per point, s")->capture_default_str();
  c->add_option("--seed", a->seed, "seed of the random offsets and tile sample")->capture_default_str();
  c->add_flag("--buffered", a->buffered, "read through the page cache instead of O_DIRECT (io.direct = false)");
  c->add_flag("--quick", a->quick, "fewer, shorter points (a smoke run; less accurate)");
  c->add_flag("--json", a->json, "print the measurements and the fitted keys as JSON");
  c->add_flag("--quiet,-q", a->quiet, "no progress or table (warnings are still printed)");
  c->callback([a] { run_calibrate(*a); });
}

}  // namespace vtsim::cli
