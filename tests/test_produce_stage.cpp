// The produce stage (stream/exec/produce.h, docs/pipeline.md): produced jobs skip the disk, wait
// for the production servers, respect the per-frame production budget, cancel at no cost, and
// never touch the disk or RAM counters.
#include <doctest/doctest.h>

#include "stream/exec/pipeline.h"
#include "stream/exec/sim_executor.h"

using namespace vtsim;

namespace {

constexpr std::uint64_t kProdTile = 65536;
// Keys with x >= 100 are produced: 1000 texels, 2 layers (cost 10 us + 1000 * 3 ns = 13 us).
TileSizer produce_sizer() {
  return [](TileKey k) {
    TileSizes s{kProdTile, kProdTile};
    if (k.x() >= 100) {
      s.disk_bytes = 0;
      s.produce = ProduceWork{1000, 2, 0};
    }
    return s;
  };
}
ProduceModel model(int workers, int budget = 0) {
  ProduceModel m;
  m.per_tile_us = 10.0;
  m.per_texel_ns = 1.0;
  m.per_layer_texel_ns = 1.0;
  m.per_decal_us = 2.0;
  m.workers = workers;
  m.tiles_per_frame = budget;
  return m;
}
Need pneed(std::int64_t x, std::uint64_t prio = 0) { return Need{TileKey(0, 0, x, 0), prio, false}; }
std::vector<UploadItem> pframe(Pipeline& p, int f, Ticks t, const std::vector<Need>& needs) {
  p.begin_frame(f, t);
  p.set_needs(needs);
  p.dispatch();
  std::vector<UploadItem> up;
  p.take_uploads(UploadBudget{}, up);
  return up;
}
PipelineConfig pcfg(int budget) {
  PipelineConfig c;
  c.produce_tiles_per_frame = budget;
  return c;
}

}  // namespace

TEST_CASE("produce stage: the model's cost, and the boundary one tick before production ends") {
  CHECK(SimExecutor::produce_ticks(model(1), ProduceWork{1000, 2, 0}) == 13'000);
  CHECK(SimExecutor::produce_ticks(model(1), ProduceWork{1000, 2, 3}) == 19'000);
  ProduceModel per_texel = model(1);
  per_texel.per_decal_texel_ns = 1.5;  // + 3 decals over 2000 texels: 3000 ns
  CHECK(SimExecutor::produce_ticks(per_texel, ProduceWork{1000, 2, 3, 2000}) == 22'000);
  SimExecutor ex(DiskModel{1000.0, 0.0, 1}, DecodeModel{}, 64, {}, model(1));
  Pipeline p(PipelineConfig{}, ex, produce_sizer());
  CHECK(pframe(p, 0, 0, {pneed(100)}).empty());
  CHECK(pframe(p, 1, 12'999, {pneed(100)}).empty());
  auto up = pframe(p, 2, 13'000, {pneed(100)});
  REQUIRE(up.size() == 1);
  CHECK(up[0].produced);
  CHECK(up[0].io_ticks == 0);
  CHECK(up[0].decode_ticks == 13'000);
  CHECK(p.counters().produced == 1);
  CHECK(p.counters().produce_ns == 13'000);
  CHECK(ex.produce_busy_ticks() == 13'000);
}

TEST_CASE("produce stage: workers serve in parallel, produced jobs never touch disk or RAM counters") {
  SimExecutor ex(DiskModel{1000.0, 0.0, 1}, DecodeModel{}, 64, {}, model(2));
  Pipeline p(PipelineConfig{}, ex, produce_sizer());
  const std::vector<Need> needs{pneed(100), pneed(101), pneed(102)};
  CHECK(pframe(p, 0, 0, needs).empty());
  CHECK(pframe(p, 1, 13'000, needs).size() == 2);  // two servers: two at 13 us
  CHECK(pframe(p, 2, 25'999, {pneed(102)}).empty());
  CHECK(pframe(p, 3, 26'000, {pneed(102)}).size() == 1);  // the third waits for a server
  const PipelineCounters& c = p.counters();
  CHECK(c.produced == 3);
  CHECK(c.disk_bytes == 0);
  CHECK(c.disk_reads == 0);
  CHECK(c.decodes == 0);
  CHECK(c.ram_hits + c.ram_misses == 0);
  CHECK(p.ram_bytes_used() == 0);
  CHECK(ex.disk_busy_ticks() == 0);
}

TEST_CASE("produce stage: the per-frame budget is respected exactly, the rest deferred and counted") {
  SimExecutor ex(DiskModel{0.0, 0.0, 0}, DecodeModel{}, 64, {}, model(0, 2));
  Pipeline p(pcfg(2), ex, produce_sizer());
  std::vector<Need> needs;
  for (int i = 0; i < 5; ++i) needs.push_back(pneed(100 + i, static_cast<std::uint64_t>(i)));
  needs.push_back(pneed(1));  // a read: not under the production budget
  p.begin_frame(0, 0);
  p.set_needs(needs);
  p.dispatch();
  CHECK(p.counters().produce_submitted == 2);
  CHECK(p.counters().produce_deferred == 3);
  CHECK(p.counters().submitted == 3);
  std::vector<UploadItem> up;
  p.take_uploads(UploadBudget{}, up);
  CHECK(up.size() == 1);  // the read (unconstrained disk) is ready now
  needs.pop_back();  // the read is resident now
  auto up1 = pframe(p, 1, 13'000, needs);
  REQUIRE(up1.size() == 2);
  CHECK(up1[0].key.x() == 100);  // priority order
  CHECK(up1[1].key.x() == 101);
  CHECK(p.counters().produce_submitted == 4);
  CHECK(p.counters().produce_deferred == 4);
}

TEST_CASE("produce stage: cancel before production starts costs nothing") {
  SimExecutor ex(DiskModel{0.0, 0.0, 0}, DecodeModel{}, 64, {}, model(1));
  Pipeline p(PipelineConfig{}, ex, produce_sizer());
  pframe(p, 0, 0, {pneed(100), pneed(101)});
  pframe(p, 1, 1000, {pneed(100)});  // 101 waits for the one server: dropped
  CHECK(p.counters().produce_cancelled == 1);
  CHECK(p.counters().cancelled_queued == 0);
  CHECK(ex.produce_busy_ticks() == 13'000);
  CHECK(pframe(p, 2, 13'000, {pneed(100)}).size() == 1);
  CHECK(ex.in_flight() == 0);
}

TEST_CASE("produce stage: two identical runs give identical results (determinism)") {
  const auto run = [] {
    SimExecutor ex(DiskModel{50.0, 100.0, 2}, DecodeModel{}, 8, {}, model(2, 3));
    Pipeline p(pcfg(3), ex, produce_sizer());
    std::vector<std::uint64_t> trace;
    for (int f = 0; f < 60; ++f) {
      std::vector<Need> needs;
      for (int i = 0; i < 8; ++i) needs.push_back(pneed((f / 10 + i) % 2 ? 100 + f / 7 + i : f / 5 + i, static_cast<std::uint64_t>(i)));
      for (const UploadItem& u : pframe(p, f, static_cast<Ticks>(f) * 16'666'667, needs)) trace.push_back(u.key.bits);
    }
    const PipelineCounters& c = p.counters();
    trace.insert(trace.end(), {c.produced, c.produce_ns, c.produce_deferred, c.disk_bytes, c.produce_cancelled});
    return trace;
  };
  CHECK(run() == run());
}
