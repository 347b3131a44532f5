#include "sim/run/runtime_setup.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "sim/run/real_replay.h"
#include "sim/run/systems.h"
#include "stream/exec/sim_executor.h"
#include "stream/throttle/i_throttle.h"

namespace vtsim {

namespace {

// What the pipeline can bring into VRAM per second: its bottleneck (for throttling).
double service_Bps(const ReplayConfig& cfg, const IStreamingSystem& system, const UploadBudget& budget, double period_s) {
  double mean_disk = 0, mean_dec = 0;
  const auto& layers = cfg.texture.layers.specs;
  for (const auto& L : layers) {
    mean_disk += static_cast<double>(tile_disk_bytes(cfg, L));
    mean_dec += static_cast<double>(tile_decoded_bytes(cfg, L));
  }
  mean_disk /= static_cast<double>(layers.size());
  mean_dec /= static_cast<double>(layers.size());
  double service;
  ProduceWork full;
  if (system.full_tile_work(full)) {
    // A produced system's tiles are rendered, not read: the production servers (and their
    // per-frame budget) are its bottleneck, so a level whose backlog takes longer than the
    // deadline to produce is clamped (issue 27: "the system says which level falls behind and
    // the throttle clamps it"). Its brush mips' reads are small beside them and not counted.
    const ProduceModel& m = cfg.produce;
    const double tile_s = produce_ns(m, full) * 1e-9;
    service = m.workers > 0 && tile_s > 0 ? m.workers * mean_dec / tile_s : std::numeric_limits<double>::infinity();
    if (m.tiles_per_frame > 0) service = std::min(service, m.tiles_per_frame * mean_dec / period_s);
  } else {
    service = disk_throughput_Bps(disk_model(cfg.disk), mean_disk) * (mean_dec / mean_disk);
    service = std::min(service, decode_throughput_Bps(cfg.decode, mean_dec));
  }
  if (budget.bytes) service = std::min(service, static_cast<double>(budget.bytes) / period_s);
  if (budget.link_ticks > 0) {  // the link's copy time a frame, at the mean tile
    const auto copy = static_cast<double>(budget.per_tile_ticks + transfer_ticks(static_cast<std::uint64_t>(mean_dec), budget.link_Bps));
    service = std::min(service, std::floor(static_cast<double>(budget.link_ticks) / copy) * mean_dec / period_s);
  }
  if (budget.tiles) service = std::min(service, budget.tiles * mean_dec / period_s);
  return std::isfinite(service) ? service : 0.0;  // 0: unlimited
}

}  // namespace

RuntimeParts runtime_parts(const ReplayConfig& cfg, TextureExtent extent, double period_s, IExecutor* executor, TileSizer sizer) {
  RuntimeParts p;
  p.system = make_system(cfg, extent);
  if (!sizer) {
    std::vector<TileSizes> by_layer;
    for (const auto& L : cfg.texture.layers.specs) by_layer.push_back({tile_disk_bytes(cfg, L), tile_decoded_bytes(cfg, L)});
    sizer = [by_layer](TileKey k) { return by_layer[k.layer() < by_layer.size() ? k.layer() : 0]; };
  }
  // The system's own tiles first: produced ones (no disk; their normal decoded size), then the
  // ones it sizes itself; the rest as the texture's layers. Called once per new request.
  p.sizer = [base = std::move(sizer), sys = p.system.get()](TileKey k) {
    ProduceWork w;
    if (sys->produced(k, w)) {
      TileSizes s = base(k);
      s.disk_bytes = 0;
      s.produce = w;
      return s;
    }
    TileSizes s;
    if (sys->tile_sizes(k, s.disk_bytes, s.decoded_bytes)) return s;
    return base(k);
  };
  p.executor = executor;
  if (!executor)
    p.owned_executor = std::make_unique<SimExecutor>(disk_model(cfg.disk), cfg.decode, static_cast<std::size_t>(cfg.io.max_in_flight),
                                                     cfg.io.faults, cfg.produce);
  PipelineConfig& pc = p.pipeline;
  pc.ram_bytes = static_cast<std::uint64_t>(cfg.ram.capacity_MiB * 1048576.0);
  pc.max_retries = cfg.io.max_retries;
  pc.retry_backoff_frames = cfg.io.retry_backoff_frames;
  pc.thrash_frames = cfg.metrics.thrash_frames;
  pc.ram_policy = cfg.ram.policy;
  pc.produce_tiles_per_frame = cfg.produce.tiles_per_frame;
  const ThrottlePolicyInfo* policy = throttle_policies().find(cfg.throttle.policy);
  if (!policy) throw InputError("config", "field 'throttle.policy': " + throttle_policies().unknown(cfg.throttle.policy));
  p.throttle = policy->make(cfg.throttle);
  // The upload budget the config and the link allow per frame.
  p.budget = UploadBudget{cfg.upload.bytes_per_frame < 0 ? 0 : static_cast<std::uint64_t>(cfg.upload.bytes_per_frame),
                          cfg.upload.tiles_per_frame < 0 ? 0 : cfg.upload.tiles_per_frame};
  if (cfg.upload.per_tile_us > 0) {
    // A fixed cost per copy: the link's budget is a frame period of copy time (upload_ticks).
    p.budget.link_ticks = seconds_to_ticks(period_s);
    p.budget.per_tile_ticks = upload_ticks(cfg.upload, 0);
    p.budget.link_Bps = cfg.upload.link_MBps * 1e6;
    std::uint64_t max_tile = 0;
    for (const auto& L : cfg.texture.layers.specs) max_tile = std::max(max_tile, tile_decoded_bytes(cfg, L));
    if (upload_ticks(cfg.upload, max_tile) > p.budget.link_ticks)
      throw InputError("config", fmt::format("field 'upload.per_tile_us': a {}-byte tile's copy takes {:.1f} us over the link, longer "
                                             "than a frame ({:.1f} us): nothing could upload",
                                             max_tile, ticks_to_seconds(upload_ticks(cfg.upload, max_tile)) * 1e6, period_s * 1e6));
  } else if (cfg.upload.link_MBps > 0) {
    const auto link_bytes = static_cast<std::uint64_t>(cfg.upload.link_MBps * 1e6 * period_s);
    p.budget.bytes = p.budget.bytes ? std::min(p.budget.bytes, link_bytes) : link_bytes;
  }
  p.frame_period_s = period_s;
  p.service_Bps = service_Bps(cfg, *p.system, p.budget, period_s);
  p.extent = extent;
  p.tile_size = cfg.texture.tile_size;
  p.layers = static_cast<int>(cfg.texture.layers.specs.size());
  return p;
}

std::unique_ptr<StreamingRuntime> make_streaming_runtime(ReplayConfig cfg, const TileStore& store, const EngineRuntimeOptions& options) {
  if (produced_system(cfg))
    throw InputError("config", "field 'run.system': the terrain produces its tiles; an engine's runtime streams a store (clipmap or vt)");
  bind_store_texture(cfg, store);  // refuses a store that does not match the config
  ThreadedExecutorConfig xc = options.executor;
  if (options.threads_from_config) {
    xc.io_threads = cfg.io.threads;
    xc.decode_workers = cfg.decode.workers;
    xc.capacity = static_cast<std::size_t>(cfg.io.max_in_flight);
    xc.direct = cfg.io.direct;
    xc.faults = cfg.io.faults;
    xc.tile_memory_bytes = static_cast<std::uint64_t>(cfg.ram.capacity_MiB * 1048576.0);
  }
  auto exec = std::make_unique<ThreadedExecutor>(store, xc);
  const double period_s = cfg.run.fps > 0 ? 1.0 / cfg.run.fps : 1.0 / 60.0;
  RuntimeParts p = runtime_parts(cfg, {cfg.texture.width, cfg.texture.height}, period_s, exec.get(), store_sizer(store));
  p.owned_executor = std::move(exec);
  return std::make_unique<StreamingRuntime>(std::move(p));
}

}  // namespace vtsim
