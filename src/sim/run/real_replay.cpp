#include "sim/run/real_replay.h"

#include <fmt/format.h>

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <thread>

#include "core/error.h"
#include "core/host_memory.h"
#include "sim/run/provenance.h"
#include "sim/run/systems.h"
#include "sim/view/scene.h"
#include "sim/trace/trace_io.h"
#include "stream/exec/threaded_executor.h"
#include "stream/produce/terrain_producer.h"
#include "stream/system/terrain_system.h"

namespace vtsim {

namespace {

const char* format_for_channels(std::uint32_t channels) {
  switch (channels) {
    case 1: return "r8";
    case 2: return "rg8";
    case 3: return "rgb8";
    default: return "rgba8";
  }
}

double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

}  // namespace

std::vector<std::string> bind_store_texture(ReplayConfig& cfg, const TileStore& store) {
  const ReplayConfig def;
  const store::Geometry& g = store.geometry();
  const std::string& path = store.path();
  auto bind = [&](const char* key, auto& value, auto def_value, auto store_value) {
    using T = std::decay_t<decltype(value)>;
    if (value != def_value && value != static_cast<T>(store_value))
      throw InputError("config", fmt::format("field '{}': {} disagrees with the store {} ({}); leave it unset to take the "
                                             "store's",
                                             key, value, path, store_value));
    value = static_cast<T>(store_value);
  };
  bind("texture.width", cfg.texture.width, def.texture.width, g.width);
  bind("texture.height", cfg.texture.height, def.texture.height, g.height);
  bind("texture.tile_size", cfg.texture.tile_size, def.texture.tile_size, g.tile);
  bind("texture.border", cfg.texture.border, def.texture.border, g.border);

  std::string layers;
  const auto totals = store.totals();
  for (std::uint32_t i = 0; i < store.layer_count(); ++i) {
    const double ratio = totals[i].stored_bytes ? static_cast<double>(totals[i].decoded_bytes) / static_cast<double>(totals[i].stored_bytes) : 1.0;
    layers += fmt::format("{}{}:{}:{:.4g}", i ? "," : "", store.layer(i).name, format_for_channels(store.layer(i).channels),
                          std::clamp(ratio, 1.0, 1000.0));
  }
  if (cfg.texture.layers.text != def.texture.layers.text) {
    const auto& want = cfg.texture.layers.specs;
    const auto have = parse_layers(layers);
    bool same = want.size() == have.size();
    for (std::size_t i = 0; same && i < want.size(); ++i) same = want[i].name == have[i].name && want[i].format == have[i].format;
    if (!same)
      throw InputError("config", "field 'texture.layers': '" + cfg.texture.layers.text + "' disagrees with the store " + path + " ('" +
                                     layers + "'); leave it unset to take the store's");
  }
  cfg.texture.layers.text = layers;
  cfg.texture.layers.specs = parse_layers(layers);
  validate(cfg);
  // The levels the system samples (the clipmap: down to 1×1; a virtual texture: down to one page).
  const SystemInfo& system = streaming_systems().at(cfg.run.system);
  const auto need = static_cast<std::uint32_t>(system.store_levels(cfg));
  if (g.levels < need)
    throw InputError(path + ": header field 'level_count'",
                     fmt::format("{} levels; {} ({}): generate the store without --levels", g.levels, system.store_levels_why, need));
  return {fmt::format("texture from the store {}: {}×{} texels, tile {}, border {}, {} levels, layers {}", path, g.width,
                      g.height, g.tile, g.border, g.levels, layers)};
}

TileSizer store_sizer(const TileStore& store) {
  return [&store](TileKey k) -> TileSizes {
    if (!store.contains(k)) return {};
    const TileLocation loc = store.locate(k);
    return {loc.read_bytes, loc.decoded_bytes};
  };
}

void apply_speed(ReplayConfig& cfg, Trace& trace, double speed) {
  if (!(speed > 0.0 && speed <= 1000.0)) throw InputError("--speed", fmt::format("{} is outside (0, 1000]", speed));
  if (speed == 1.0) return;
  if (cfg.run.fps * speed > 10000.0)  // the resampler's limit (trace_resample.cpp)
    throw InputError("--speed", fmt::format("{} times run.fps {} is above 10000 frames/s", speed, cfg.run.fps));
  for (const Pose& p : trace.poses)
    if (std::abs(p.t_s / speed) > kMaxAbsTime_s)
      throw InputError("--speed", fmt::format("{} stretches the trace's time {} s beyond +-{:g} s", speed, p.t_s, kMaxAbsTime_s));
  for (Pose& p : trace.poses) p.t_s /= speed;
  cfg.run.fps *= speed;
}

bool produced_system(const ReplayConfig& cfg) { return streaming_systems().at(cfg.run.system).caps.produces_tiles; }

void check_real_clock_system(const ReplayConfig& cfg, bool have_store) {
  if (!produced_system(cfg)) {
    if (!have_store)
      throw InputError("--store", "the real clock reads a tile store: give --store S (make one with `vtsim store gen`)");
    return;
  }
  // The terrain stores nothing the tile path reads: its tiles are composed and its brush mips
  // served from memory by the TerrainProducer (docs/produced.md, "The real clock").
  if (have_store)
    throw InputError("--store", fmt::format("run.system '{}' produces its tiles and serves its brush mips from memory in the real "
                                            "clock (docs/produced.md, \"The real clock\"): it reads no store; drop --store",
                                            cfg.run.system));
  for (const LayerSpec& L : cfg.texture.layers.specs)
    if (L.format != "rgba8")
      throw InputError("config", fmt::format("field 'texture.layers': layer '{}' is {}; the terrain's CPU compositor writes rgba8 "
                                             "only (the real clock composes every layer)",
                                             L.name, L.format));
  if (cfg.produce.workers < 1 || cfg.produce.workers > 1024)
    throw InputError("config", fmt::format("field 'produce.workers': {}; the real clock runs that many production threads (1 to "
                                           "1024; 0 = unlimited is the simulated clock's only)",
                                           cfg.produce.workers));
}

produce::TerrainProducerParams terrain_producer_params(const ReplayConfig& cfg) {
  produce::TerrainProducerParams p;
  p.width = static_cast<std::uint64_t>(cfg.texture.width);
  p.height = static_cast<std::uint64_t>(cfg.texture.height);
  p.tile = cfg.texture.tile_size;
  p.border = cfg.texture.border;
  p.texels_per_m = cfg.texture.texels_per_m;
  p.brushes_per_sector = cfg.terrain.brushes_per_sector;
  p.brush_size = cfg.terrain.brush_size;
  p.brush_period_m = cfg.terrain.brush_period_m;
  p.brush_tree_levels = cfg.terrain.brush_tree_levels;
  p.mask_size = cfg.terrain.mask_size;
  p.sector_m = cfg.terrain.sector_m;
  p.brush_layer = TerrainSystem::kBrushLayer;
  for (std::size_t at = 0; !cfg.terrain.brush_files.empty() && at <= cfg.terrain.brush_files.size();) {
    const std::size_t comma = std::min(cfg.terrain.brush_files.find(',', at), cfg.terrain.brush_files.size());
    std::string f = cfg.terrain.brush_files.substr(at, comma - at);
    f.erase(0, f.find_first_not_of(" \t"));
    f.erase(f.find_last_not_of(" \t") + 1);
    if (f.empty()) throw InputError("config", fmt::format("field 'terrain.brush_files': an empty name in '{}'", cfg.terrain.brush_files));
    p.brush_files.push_back(std::move(f));
    at = comma + 1;
  }
  return p;
}

namespace {

// Host memory the size of the RAM cache and of the VRAM the arena stands for, allocated before
// the first frame: both must fit together in what this process may use, checked before either
// is allocated (core/host_memory.h says why). Returns the arena; `layer_bytes` its layers' tile sizes.
std::unique_ptr<VramArena> real_clock_arena(const ReplayConfig& cfg, const TileStore* store, const ThreadedExecutorConfig& xc,
                                            const RealClockOptions& options, std::vector<std::uint32_t>& layer_bytes) {
  const std::uint64_t usable = options.memory_limit_bytes > 0 ? options.memory_limit_bytes : usable_memory_bytes();
  const auto mib = [](std::uint64_t b) { return static_cast<double>(b) / 1048576.0; };
  const std::uint64_t reserve = store ? ThreadedExecutor::reserved_pages(*store, xc) * ThreadedExecutor::page_bytes(*store) : 0;
  if (reserve > usable)
    throw InputError("config", fmt::format("field 'ram.capacity_MiB': the RAM cache's buffers need {:.1f} MiB, more than "
                                           "the {:.1f} MiB of memory this process may use",
                                           mib(reserve), mib(usable)));
  if (store)
    for (std::uint32_t i = 0; i < store->layer_count(); ++i) layer_bytes.push_back(store->tile_bytes(i));
  else
    for (const LayerSpec& L : cfg.texture.layers.specs) layer_bytes.push_back(static_cast<std::uint32_t>(tile_decoded_bytes(cfg, L)));
  const SystemInfo& system = streaming_systems().at(cfg.run.system);
  try {
    return std::make_unique<VramArena>(system.vram_arena(cfg, layer_bytes, usable - reserve));
  } catch (const VramArena::ArenaTooLarge& e) {
    throw InputError("config", fmt::format("field '{}': the VRAM arena needs {:.1f} MiB, more than the {:.1f} MiB of "
                                           "memory this process may use ({:.1f} MiB) less the RAM cache's buffers "
                                           "({:.1f} MiB, ram.capacity_MiB)",
                                           system.vram_field, mib(e.bytes), mib(e.limit), mib(usable), mib(reserve)));
  } catch (const std::bad_alloc&) {
    throw InputError("config", fmt::format("field '{}': the VRAM arena does not fit in host memory", system.vram_field));
  }
}

// The tiles the pipeline gave up on (faulted more than io.max_retries times in a row), named so
// a corrupt store can be repaired: the first kMaxListed in key order; `more`: how many more.
nlohmann::json failed_tiles_json(const ThreadedExecutor& exec, const ReplayConfig& cfg, std::size_t& more) {
  constexpr std::size_t kMaxListed = 50;  // enough to see a pattern (one level, one file region), small in the JSON
  nlohmann::json failed = nlohmann::json::array();
  std::size_t& failed_more = more;
  failed_more = 0;
  for (const ThreadedExecutor::TileFaults& t : exec.faulted_tiles()) {
    if (t.in_a_row <= static_cast<std::uint32_t>(cfg.io.max_retries)) continue;
    if (failed.size() == kMaxListed) {
      ++failed_more;
      continue;
    }
    failed.push_back({{"layer", t.key.layer()}, {"level", t.key.level()}, {"x", t.key.x()}, {"y", t.key.y()},
                      {"fault", std::string(fault_name(t.fault))}, {"reason", t.error}, {"attempts", t.in_a_row}});
  }
  return failed;
}

RealRun run_real(const ReplayConfig& cfg, const Trace& trace, const IScene& scene, const TileStore* store,
                 const RealClockOptions& options) {
  check_real_clock_system(cfg, store != nullptr);
  // Start-up, until frame 0: buffers reserved, workers warmed, the arena allocated, the first view
  // rendered (docs/real-engine.md §2, §7a).
  const auto setup_start = std::chrono::steady_clock::now();
  double startup_s = 0;
  ThreadedExecutorConfig xc;
  xc.io_threads = cfg.io.threads;
  xc.decode_workers = cfg.decode.workers;
  xc.capacity = static_cast<std::size_t>(cfg.io.max_in_flight);
  xc.direct = cfg.io.direct;
  xc.io_engine = io_engines().at(cfg.io.engine).engine;
  xc.queue_depth = cfg.io.queue_depth;
  xc.faults = cfg.io.faults;
  xc.tile_memory_bytes = static_cast<std::uint64_t>(cfg.ram.capacity_MiB * 1048576.0);

  std::vector<std::uint32_t> layer_bytes;
  RealRun run;
  run.arena = real_clock_arena(cfg, store, xc, options, layer_bytes);
  VramArena& arena = *run.arena;
  // The terrain: production threads only (produce.workers), composing and serving from one
  // shared scene built here, before frame 0 (its build is start-up).
  std::unique_ptr<produce::TerrainProducer> producer;
  if (!store) {
    producer = std::make_unique<produce::TerrainProducer>(terrain_producer_params(cfg));
    producer->record_tiles(options.record_produced_tiles);
    xc.producer = producer.get();
    xc.produce_workers = cfg.produce.workers;
  }
  std::optional<ThreadedExecutor> exec_holder;
  if (store) exec_holder.emplace(*store, xc);
  else exec_holder.emplace(xc);
  ThreadedExecutor& exec = *exec_holder;

  // Frame pacing: frame f starts at its trace time on the wall clock, or as soon as the previous
  // frame is done when the loop runs late (the lateness is measured, not hidden).
  const double period_s = cfg.run.fps > 0 ? 1.0 / cfg.run.fps : 1.0 / 60.0;
  const Ticks half_period = seconds_to_ticks(period_s / 2);
  std::uint64_t late_frames = 0, no_data = 0;
  Ticks max_late = 0, sum_late = 0;
  int frames = 0;
  std::vector<std::pair<int, double>> late_list;  // (frame, ms late): the first 20 late frames
  ReplayEnv env;
  env.executor = &exec;
  if (store) env.sizer = store_sizer(*store);  // the terrain: the config's layers size its tiles (as the simulated clock)
  env.clock_name = "real";
  if (producer)
    env.on_start = [&producer](IStreamingSystem& sys) {
      if (const auto* terrain = dynamic_cast<const TerrainSystem*>(&sys)) producer->set_decals(terrain->decal_layer());
    };
  env.progress = options.progress;
  // The frame loop's own cost: wall and CPU time (this thread) from one frame's start to the next
  // frame's pacing point. Wall well above CPU means the thread waited for a core.
  std::vector<double> work_wall_ms, work_cpu_ms;
  Ticks frame_start = 0;
  double cpu_start = 0;
  env.pace = [&](int f, Ticks target) -> Ticks {
    if (f > 0) {
      work_wall_ms.push_back(ticks_to_ms(exec.now() - frame_start));
      work_cpu_ms.push_back(thread_cpu_ms() - cpu_start);
    }
    if (f == 0) {
      startup_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - setup_start).count();
      exec.restart_clock();
    }
    std::this_thread::sleep_until(exec.clock().at(target));
    const Ticks now = exec.now();
    const Ticks late = std::max<Ticks>(0, now - target);
    max_late = std::max(max_late, late);
    sum_late += late;
    if (late > half_period) {
      ++late_frames;
      if (late_list.size() < 20) late_list.push_back({f, ticks_to_ms(late)});
    }
    ++frames;
    frame_start = now;
    cpu_start = thread_cpu_ms();
    return now;
  };
  const auto arena_layers = static_cast<std::uint32_t>(layer_bytes.size());
  std::uint64_t brush_uploads = 0;
  env.on_upload = [&](const UploadItem& u, std::int64_t slot) {
    // The terrain's brush mips stay in RAM for the CPU compositor: no VRAM slot.
    if (u.key.layer() >= arena_layers) {
      brush_uploads += u.data != nullptr;
      no_data += u.data == nullptr;
      return;
    }
    if (u.data) arena.upload(*u.data, slot);
    else ++no_data;
  };
  // VT: every page complete in the pool must be in the arena at its slot, every layer.
  std::uint64_t pool_layers_missing = 0;
  env.on_finish = [&](const IStreamingSystem& sys) {
    sys.pool_pages(run.pool_pages);
    for (const auto& [page, slot] : run.pool_pages)
      for (std::uint32_t layer = 0; layer < arena_layers; ++layer)
        pool_layers_missing += arena.peek(TileKey(layer, page.level(), page.x(), page.y()), slot).empty();
  };
  run.result = run_replay(cfg, trace, scene, env);
  exec.shutdown();

  const VramArena::Stats& as = arena.stats();
  const FaultLayer::Counts inj = exec.injected_faults();
  nlohmann::json& rc = run.result.summary["real_clock"];
  rc["io_threads"] = exec.io_threads();
  rc["decode_workers"] = exec.decode_workers();
  rc["max_in_flight"] = cfg.io.max_in_flight;
  rc["o_direct"] = exec.direct();
  rc["o_direct_warning"] = exec.direct_warning();
  rc["io_engine"] = std::string(engine_name(exec.io_engine()));
  rc["io_queue_depth"] = exec.io_queue_depth();
  rc["io_engine_warning"] = exec.io_engine_warning();
  rc["startup_s"] = startup_s;
  rc["late_frames"] = late_frames;
  rc["first_late_frames"] = late_list;
  rc["max_late_ms"] = ticks_to_ms(max_late);
  rc["mean_late_ms"] = frames ? ticks_to_ms(sum_late) / frames : 0.0;
  rc["uploads_without_data"] = no_data;
  rc["frame_work_ms"] = {{"wall", to_json(percentiles(work_wall_ms))}, {"cpu", to_json(percentiles(work_cpu_ms))}};
  rc["vram_arena"] = {{"capacity_MiB", static_cast<double>(arena.capacity_bytes()) / 1048576.0},
                      {"uploads", as.uploads},
                      {"bytes", as.bytes},
                      {"overwrites", as.overwrites},
                      {"copy_ms", static_cast<double>(as.copy_ns) * 1e-6}};
  if (arena.pool()) {
    rc["vram_arena"]["pool_pages_complete"] = run.pool_pages.size();
    rc["vram_arena"]["pool_layers_missing"] = pool_layers_missing;  // 0 unless the arena lost an upload
  }
  rc["injected_faults"] = {{"io_error", inj.io_error}, {"short_read", inj.short_read}, {"checksum", inj.checksum}, {"slow", inj.slow}};
  rc["fault_examples"] = exec.fault_examples();
  std::size_t failed_more = 0;
  rc["failed_tiles"] = failed_tiles_json(exec, cfg, failed_more);
  rc["failed_tiles_not_listed"] = failed_more;
  if (producer) {
    rc["producer"] = {{"kind", cfg.run.system},  // the system that produces its tiles
                      {"produce_workers", cfg.produce.workers},
                      {"tiles_composed", producer->tiles()},
                      {"brush_mips_served", producer->brushes()},
                      {"brush_bytes_served", producer->brush_bytes_served()},
                      {"decals_drawn", producer->decals_drawn()},
                      {"brush_commits", brush_uploads}};
    run.produced_tiles = producer->recorded_tiles();
  }
  run.result.summary["provenance"]["machine"] = machine_json();  // what the real-clock figures measured
  return run;
}

}  // namespace

RealRun run_real_replay(const ReplayConfig& cfg, const Trace& trace, const IScene& scene, const TileStore& store,
                        const RealClockOptions& options) {
  return run_real(cfg, trace, scene, &store, options);
}

RealRun run_real_replay(const ReplayConfig& cfg, const Trace& trace, const IScene& scene, const RealClockOptions& options) {
  return run_real(cfg, trace, scene, nullptr, options);
}

}  // namespace vtsim
