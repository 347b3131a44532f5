#include <doctest/doctest.h>

#include "stream/exec/sim_executor.h"

using namespace vtsim;

namespace {
TileJob job(RequestId id, std::uint64_t disk, std::uint64_t decoded, std::uint64_t prio = 0) {
  return TileJob{id, TileKey(0, 0, static_cast<std::int64_t>(id), 0), disk, decoded, prio};
}
}  // namespace

TEST_CASE("sim executor: a read completes exactly at latency + bytes / bandwidth, not one tick before") {
  // 100 us latency, 100 MB/s: 1,000,000 bytes transfer in 10 ms. Ready at 10.1 ms = 10,100,000 ticks.
  SimExecutor ex(DiskModel{100.0, 100.0, 1}, DecodeModel{0.0, 0.0, 1}, 8);
  ex.submit(job(1, 1'000'000, 4'000'000));
  std::vector<JobResult> out;
  ex.collect(10'099'999, out);
  CHECK(out.empty());
  ex.collect(10'100'000, out);
  REQUIRE(out.size() == 1);
  CHECK(out[0].outcome == JobOutcome::ready);
  CHECK(out[0].read_start == 0);
  CHECK(out[0].read_end == 10'100'000);
  CHECK(out[0].decode_end == 10'100'000);
  CHECK(out[0].bytes_read == 1'000'000);
  CHECK(ex.in_flight() == 0);
}

TEST_CASE("sim executor: latencies overlap across channels, transfers share one bus") {
  // Two channels, 1 ms latency, 1 MB/s bus, 1000-byte reads (1 ms transfer each).
  SimExecutor ex(DiskModel{1000.0, 1.0, 2}, DecodeModel{}, 8);
  ex.submit(job(1, 1000, 1000));
  ex.submit(job(2, 1000, 1000));
  std::vector<JobResult> out;
  ex.collect(10'000'000, out);
  REQUIRE(out.size() == 2);
  CHECK(out[0].id == 1);
  CHECK(out[0].read_end == 2'000'000);  // 1 ms latency + 1 ms transfer
  CHECK(out[1].id == 2);
  CHECK(out[1].read_end == 3'000'000);  // its transfer waits for the bus
}

TEST_CASE("sim executor: a disk with queue depth keeps channels x queue_depth reads in service (io_uring)") {
  // 2 channels x depth 3, 1 ms latency, unlimited bus: 7 reads start 6 at once, the 7th when one ends.
  SimExecutor ex(DiskModel{1000.0, 0.0, 2, 3}, DecodeModel{}, 16);
  for (RequestId id = 1; id <= 7; ++id) ex.submit(job(id, 1000, 1000));
  std::vector<JobResult> out;
  ex.collect(10'000'000, out);
  REQUIRE(out.size() == 7);
  for (std::size_t i = 0; i < 6; ++i) CHECK(out[i].read_end == 1'000'000);
  CHECK(out[6].read_start == 1'000'000);
  CHECK(out[6].read_end == 2'000'000);
  CHECK(disk_slots(DiskModel{1000.0, 0.0, 2, 3}) == 6);
  CHECK(disk_slots(DiskModel{1000.0, 0.0, 0, 3}) == 0);  // unlimited
  // Little's law over the slots, capped by the bus: 6 x 1000 B / 1 ms = 6 MB/s; a 4 MB/s bus caps it.
  CHECK(disk_throughput_Bps(DiskModel{1000.0, 0.0, 2, 3}, 1000) == doctest::Approx(6e6));
  CHECK(disk_throughput_Bps(DiskModel{1000.0, 4.0, 2, 3}, 1000) == doctest::Approx(4e6));
  DiskConfig dc;
  dc.channels = 4;
  dc.queue_depth = 16;
  CHECK(disk_slots(disk_model(dc)) == 64);
}

TEST_CASE("sim executor: queued jobs start by priority, then submission order") {
  SimExecutor ex(DiskModel{0.0, 1.0, 1}, DecodeModel{}, 16);  // 1 MB/s: 1000 bytes = 1 ms
  ex.submit(job(1, 1000, 1000, 9));  // starts at once: the channel is free
  ex.submit(job(2, 1000, 1000, 5));
  ex.submit(job(3, 1000, 1000, 1));
  ex.submit(job(4, 1000, 1000, 5));
  std::vector<JobResult> out;
  ex.collect(100'000'000, out);
  REQUIRE(out.size() == 4);
  CHECK(out[0].id == 1);
  CHECK(out[1].id == 3);
  CHECK(out[2].id == 2);
  CHECK(out[3].id == 4);
  CHECK(out[3].read_end == 4'000'000);
}

TEST_CASE("sim executor: cancel drops queued jobs for free and reports reads under way") {
  SimExecutor ex(DiskModel{0.0, 1.0, 1}, DecodeModel{}, 16);
  ex.submit(job(1, 1000, 1000));
  ex.submit(job(2, 1000, 1000));
  CHECK(ex.cancel(2));        // still queued: dropped, never reported
  CHECK_FALSE(ex.cancel(1));  // reading: the read is paid, decode skipped
  CHECK_FALSE(ex.cancel(99));
  std::vector<JobResult> out;
  ex.collect(100'000'000, out);
  REQUIRE(out.size() == 1);
  CHECK(out[0].id == 1);
  CHECK(out[0].outcome == JobOutcome::cancelled);
  CHECK(out[0].bytes_read == 1000);
  CHECK(ex.in_flight() == 0);
}

TEST_CASE("sim executor: decode workers queue decodes, and per-tile cost and throughput add up") {
  // Instant disk; one decode worker at 1 MB/s + 100 us per tile: 1000 bytes decode in 1.1 ms.
  SimExecutor ex(DiskModel{0.0, 0.0, 0}, DecodeModel{1.0, 100.0, 1}, 16);
  ex.submit(job(1, 10, 1000));
  ex.submit(job(2, 10, 1000));
  std::vector<JobResult> out;
  ex.collect(100'000'000, out);
  REQUIRE(out.size() == 2);
  CHECK(out[0].decode_end == 1'100'000);
  CHECK(out[1].decode_start == 1'100'000);
  CHECK(out[1].decode_end == 2'200'000);
}

TEST_CASE("sim executor: injected faults are deterministic per tile") {
  auto run = [] {
    SimExecutor ex(DiskModel{10.0, 100.0, 4}, DecodeModel{}, 64, SimFaultModel{0.3, 7});
    for (RequestId i = 1; i <= 50; ++i) ex.submit(job(i, 1000, 1000));
    std::vector<JobResult> out;
    ex.collect(1'000'000'000, out);
    std::vector<int> outcome;
    for (auto& r : out) outcome.push_back(static_cast<int>(r.outcome) * 1000 + static_cast<int>(r.id));
    return outcome;
  };
  const auto a = run(), b = run();
  CHECK(a == b);
  int failed = 0;
  for (int x : a) failed += x / 1000 == static_cast<int>(JobOutcome::failed);
  CHECK(failed > 5);
  CHECK(failed < 30);
}
