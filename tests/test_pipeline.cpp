#include <doctest/doctest.h>

#include <random>

#include "stream/exec/pipeline.h"
#include "stream/exec/sim_executor.h"

using namespace vtsim;

namespace {

constexpr std::uint64_t kTile = 65536;
TileSizer fixed_sizer(std::uint64_t disk = kTile, std::uint64_t decoded = kTile) {
  return [=](TileKey) { return TileSizes{disk, decoded}; };
}
Need need(std::int64_t x, std::uint32_t level = 0, bool prefetch = false) {
  return Need{TileKey(0, level, x, 0), make_priority(level, 0, 0), prefetch};
}

// One frame of the pipeline's protocol; returns the uploaded tiles.
std::vector<UploadItem> frame(Pipeline& p, int f, Ticks t, const std::vector<Need>& needs, UploadBudget b = {}) {
  p.begin_frame(f, t);
  p.set_needs(needs);
  p.dispatch();
  std::vector<UploadItem> up;
  p.take_uploads(b, up);
  return up;
}

}  // namespace

TEST_CASE("pipeline: with unconstrained devices a needed tile uploads in the frame that needs it") {
  SimExecutor ex(DiskModel{0.0, 0.0, 0}, DecodeModel{}, 64);
  Pipeline p(PipelineConfig{}, ex, fixed_sizer());
  auto up = frame(p, 0, 0, {need(1), need(2)});
  CHECK(up.size() == 2);
  CHECK(p.live_requests() == 0);
  CHECK(p.counters().disk_bytes == 2 * kTile);
  CHECK(up[0].needed_frame == 0);
}

TEST_CASE("pipeline: boundary — one tick before IO completes not uploadable, at it uploadable") {
  // 1 ms latency, unlimited bandwidth: the tile is in RAM at exactly 1,000,000 ticks.
  SimExecutor ex(DiskModel{1000.0, 0.0, 1}, DecodeModel{}, 64);
  Pipeline p(PipelineConfig{}, ex, fixed_sizer());
  CHECK(frame(p, 0, 0, {need(7)}).empty());
  CHECK(frame(p, 1, 999'999, {need(7)}).empty());
  auto up = frame(p, 2, 1'000'000, {need(7)});
  REQUIRE(up.size() == 1);
  CHECK(up[0].io_ticks == 1'000'000);
  CHECK(up[0].needed_time == 0);
  CHECK(up[0].needed_frame == 0);
}

TEST_CASE("pipeline: a tile no longer needed is cancelled before IO when still queued") {
  // One channel, 10 ms per read: tile 1 is reading, tiles 2..4 wait in the executor's queue.
  SimExecutor ex(DiskModel{10000.0, 0.0, 1}, DecodeModel{}, 64);
  Pipeline p(PipelineConfig{}, ex, fixed_sizer());
  frame(p, 0, 0, {need(1), need(2), need(3), need(4)});
  CHECK(p.live_requests() == 4);
  frame(p, 1, 1'000'000, {need(1)});  // 2..4 no longer needed
  CHECK(p.counters().cancelled_queued == 3);
  CHECK(p.live_requests() == 1);
  auto up = frame(p, 2, 10'000'000, {need(1)});
  CHECK(up.size() == 1);
  CHECK(p.counters().disk_reads == 1);  // nothing else cost IO
}

TEST_CASE("pipeline: cancelling a read under way wastes the read, needing it again revives it") {
  SimExecutor ex(DiskModel{10000.0, 0.0, 1}, DecodeModel{}, 64);
  Pipeline p(PipelineConfig{}, ex, fixed_sizer());
  frame(p, 0, 0, {need(1)});
  frame(p, 1, 1'000'000, {});  // reading: cannot be dropped for free
  CHECK(p.live_requests() == 1);
  frame(p, 2, 10'000'000, {});  // read done, nobody needs it
  CHECK(p.counters().cancelled_after_read == 1);
  CHECK(p.counters().wasted_read_bytes == kTile);
  CHECK(p.live_requests() == 0);

  frame(p, 3, 20'000'000, {need(2)});
  frame(p, 4, 21'000'000, {});        // cancel while reading ...
  auto up = frame(p, 5, 22'000'000, {need(2)});  // ... and need it again before the read ends
  CHECK(up.empty());
  frame(p, 6, 30'000'000, {need(2)});  // read done but decode was skipped: read again
  up = frame(p, 7, 40'000'000, {need(2)});
  CHECK(up.size() == 1);
}

TEST_CASE("pipeline: RAM cache hits skip IO and decode") {
  SimExecutor ex(DiskModel{0.0, 0.0, 0}, DecodeModel{}, 64);
  Pipeline p(PipelineConfig{}, ex, fixed_sizer());
  CHECK(frame(p, 0, 0, {need(1)}).size() == 1);
  const auto reads = p.counters().disk_reads;
  auto up = frame(p, 1, 1, {need(1)});  // e.g. evicted from VRAM and needed again
  REQUIRE(up.size() == 1);
  CHECK(up[0].ram_hit);
  CHECK(p.counters().disk_reads == reads);
  CHECK(p.counters().ram_hits == 1);
}

TEST_CASE("pipeline: the RAM cache never exceeds its capacity, and a miss soon after an eviction is thrash") {
  SimExecutor ex(DiskModel{0.0, 0.0, 0}, DecodeModel{}, 64);
  PipelineConfig pc;
  pc.ram_bytes = 3 * kTile;
  Pipeline p(pc, ex, fixed_sizer());
  for (int i = 0; i < 10; ++i) {
    frame(p, i, i, {need(i)});
    CHECK(p.ram_bytes_used() <= pc.ram_bytes);
  }
  CHECK(p.counters().ram_evictions == 7);
  frame(p, 10, 10, {need(0)});  // evicted at frame 3, needed again at 10
  CHECK(p.counters().ram_thrash == 1);
}

TEST_CASE("pipeline: the upload budget is never exceeded, coarse levels upload first") {
  SimExecutor ex(DiskModel{0.0, 0.0, 0}, DecodeModel{}, 1024);
  Pipeline p(PipelineConfig{}, ex, fixed_sizer());
  std::mt19937 rng(42);
  std::vector<Need> needs;
  for (int f = 0; f < 50; ++f) {
    std::uniform_int_distribution<int> n(0, 40), lvl(0, 5);
    for (int k = n(rng); k > 0; --k) {
      const auto l = static_cast<std::uint32_t>(lvl(rng));
      needs.push_back(Need{TileKey(0, l, f * 100 + k, 0), make_priority(l, 0, 0), false});
    }
    const UploadBudget b{3 * kTile + 1, 5};
    auto up = frame(p, f, f * 1000, needs, b);
    std::uint64_t bytes = 0;
    for (auto& u : up) bytes += u.bytes;
    CHECK(up.size() <= 5);
    CHECK(bytes <= b.bytes);
    for (std::size_t i = 1; i < up.size(); ++i) CHECK(up[i - 1].key.level() >= up[i].key.level());
    // Keep needing what has not been uploaded.
    std::vector<Need> rest;
    for (auto& nd : needs) {
      bool done = false;
      for (auto& u : up) done |= u.key == nd.key;
      if (!done) rest.push_back(nd);
    }
    needs.swap(rest);
  }
}

TEST_CASE("pipeline: faulted reads retry, then fail and are not requested again, the frame loop never blocks") {
  SimExecutor ex(DiskModel{0.0, 0.0, 0}, DecodeModel{}, 64, SimFaultModel{1.0, 3});  // every read fails
  PipelineConfig pc;
  pc.max_retries = 2;
  pc.retry_backoff_frames = 1;
  Pipeline p(pc, ex, fixed_sizer());
  for (int f = 0; f < 20; ++f) CHECK(frame(p, f, f * 1000, {need(5)}).empty());
  CHECK(p.counters().faults == 3);  // first attempt + 2 retries
  CHECK(p.counters().retries == 2);
  CHECK(p.counters().failed_tiles == 1);
  CHECK(p.is_failed(TileKey(0, 0, 5, 0)));
  CHECK(p.live_requests() == 0);
}

TEST_CASE("pipeline: prefetch fills RAM without uploading, a later need is a prefetch hit") {
  SimExecutor ex(DiskModel{0.0, 0.0, 0}, DecodeModel{}, 64);
  Pipeline p(PipelineConfig{}, ex, fixed_sizer());
  CHECK(frame(p, 0, 0, {need(1, 0, true)}).empty());
  CHECK(p.counters().prefetch_disk_bytes == kTile);
  CHECK(p.in_ram(TileKey(0, 0, 1, 0)));
  auto up = frame(p, 1, 1, {need(1)});
  REQUIRE(up.size() == 1);
  CHECK(up[0].ram_hit);
  CHECK(up[0].prefetched);
  CHECK(p.counters().prefetch_hits == 1);
}

TEST_CASE("pipeline: two identical runs give identical counters (determinism)") {
  auto run = [] {
    SimExecutor ex(DiskModel{80.0, 3000.0, 4}, DecodeModel{500.0, 20.0, 2}, 32, SimFaultModel{0.05, 9});
    Pipeline p(PipelineConfig{}, ex, fixed_sizer(30000, kTile));
    std::mt19937 rng(1);
    std::vector<std::uint64_t> trace;
    for (int f = 0; f < 200; ++f) {
      std::vector<Need> needs;
      for (int k = 0; k < 30; ++k)
        needs.push_back(need(static_cast<std::int64_t>(rng() % 64), static_cast<std::uint32_t>(rng() % 4)));
      auto up = frame(p, f, static_cast<Ticks>(f) * 16'666'667, needs, UploadBudget{0, 8});
      for (auto& u : up) trace.push_back(u.key.bits ^ static_cast<std::uint64_t>(u.io_ticks));
    }
    trace.push_back(p.counters().disk_bytes);
    trace.push_back(p.counters().cancelled_queued);
    return trace;
  };
  CHECK(run() == run());
}
