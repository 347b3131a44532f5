// The threaded executor (src/stream/exec/threaded_executor.h) honours IExecutor's contract like the
// simulated one: one result per job unless cancel() returned true, completion order, collect()
// never returns the future and never blocks; decoded tiles equal the store's; cancellation in
// every state; shutdown with work in flight.
#include <doctest/doctest.h>

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <set>

#include "real_test_util.h"
#include "stream/exec/threaded_executor.h"
#include "core/tile_data.h"

// Threaded code: also run by the TSan variant of scripts/test.sh (ctest -L threads).
TEST_SUITE_BEGIN("threads");

using namespace vtsim;
using vtsim::test::eventually;

namespace {

// Collects until `n` results arrived (with a deadline); fails the test otherwise.
std::vector<JobResult> collect_all(ThreadedExecutor& ex, std::size_t n) {
  std::vector<JobResult> out;
  REQUIRE(eventually([&] {
    ex.collect(ex.now(), out);
    return out.size() >= n;
  }));
  return out;
}

ThreadedExecutorConfig exec_cfg(int io, int dec, std::size_t cap, FaultConfig f = {}) {
  ThreadedExecutorConfig c;
  c.io_threads = io;
  c.decode_workers = dec;
  c.capacity = cap;
  c.faults = f;
  return c;
}

}  // namespace

TEST_CASE("threaded executor: every tile read and decoded equals the store's, stamps ordered, completion order") {
  const TileStore store = TileStore::open(test::small_store());
  ThreadedExecutor ex(store, exec_cfg(3, 2, 1024));
  const auto keys = test::all_keys(store);
  for (std::size_t i = 0; i < keys.size(); ++i) ex.submit(test::tile_job(store, i + 1, keys[i], i % 5));
  CHECK(ex.in_flight() <= keys.size());
  const auto out = collect_all(ex, keys.size());
  REQUIRE(out.size() == keys.size());
  std::set<RequestId> ids;
  Ticks last = 0;
  for (const JobResult& r : out) {
    ids.insert(r.id);
    REQUIRE(r.outcome == JobOutcome::ready);
    CHECK(r.key == keys[r.id - 1]);
    CHECK(r.submitted <= r.read_start);
    CHECK(r.read_start <= r.read_end);
    CHECK(r.read_end <= r.decode_start);
    CHECK(r.decode_start <= r.decode_end);
    CHECK(r.decode_end >= last);  // completion order
    last = r.decode_end;
    CHECK(r.bytes_read == store.locate(r.key).read_bytes);
    REQUIRE(r.data);
    CHECK(r.data->key == r.key);
    const auto want = test::decoded(store, r.key);
    REQUIRE(r.data->bytes == want.size());
    CHECK(std::equal(want.begin(), want.end(), r.data->texels.get()));
  }
  CHECK(ids.size() == keys.size());
  CHECK(ex.in_flight() == 0);
}

// Resident pages of [p, p + bytes) by mincore.
static std::size_t resident_pages(const std::uint8_t* p, std::size_t bytes) {
  const auto page = static_cast<std::uintptr_t>(sysconf(_SC_PAGESIZE));
  const std::uintptr_t lo = reinterpret_cast<std::uintptr_t>(p) / page * page;
  const std::size_t n = (reinterpret_cast<std::uintptr_t>(p) + bytes - lo + page - 1) / page;
  std::vector<unsigned char> v(n);
  REQUIRE(mincore(reinterpret_cast<void*>(lo), n * page, v.data()) == 0);
  return static_cast<std::size_t>(std::count_if(v.begin(), v.end(), [](unsigned char c) { return (c & 1) != 0; }));
}

TEST_CASE("tile buffers: reserved ones come with their pages mapped, are handed out first and kept when released") {
  // 33 MiB is above malloc's largest mmap threshold (32 MiB), so each buffer is a new mapping:
  // untouched, its pages are not resident; reserved, every page is, before anything writes it.
  constexpr std::size_t kBytes = (33u << 20) + 100;
  constexpr std::size_t kPages = kBytes / 4096;
  auto fresh = std::make_unique_for_overwrite<std::uint8_t[]>(kBytes);
  CHECK(resident_pages(fresh.get(), kBytes) < kPages / 2);
  auto pool = std::make_shared<TileBufferPool>(1);
  pool->reserve(kBytes, 2);
  CHECK(pool->free_buffers(kBytes) == 2);
  std::vector<std::unique_ptr<std::uint8_t[]>> got;
  for (int i = 0; i < 2; ++i) {
    got.push_back(pool->acquire(kBytes));
    CHECK(resident_pages(got.back().get(), kBytes) >= kPages);
  }
  CHECK(pool->free_buffers(kBytes) == 0);
  got.push_back(std::move(fresh));  // one more than the reserve
  for (auto& b : got) pool->release(std::move(b), kBytes);
  CHECK(pool->free_buffers(kBytes) == 2);  // the reserve raised what is kept above max_free (1)
  pool->release(std::make_unique_for_overwrite<std::uint8_t[]>(100), 100);
  CHECK(pool->free_buffers(100) == 1);  // another size, its own list
  CHECK(pool->free_buffers(kBytes) == 2);
}

TEST_CASE("threaded executor: collect(until) never hands out a result completed after `until`") {
  const TileStore store = TileStore::open(test::small_store());
  ThreadedExecutor ex(store, exec_cfg(2, 1, 64));
  ex.restart_clock();
  const Ticks before = ex.now();
  for (RequestId id = 1; id <= 8; ++id) ex.submit(test::tile_job(store, id, TileKey(0, 0, static_cast<std::int64_t>(id), 0)));
  REQUIRE(ex.wait_for_results(8, std::chrono::seconds(10)));
  std::vector<JobResult> out;
  ex.collect(before, out);  // everything completed after `before`
  CHECK(out.empty());
  CHECK(ex.in_flight() == 8);  // completed results still count until collected
  ex.collect(ex.now(), out);
  CHECK(out.size() == 8);
  for (const auto& r : out) CHECK(r.decode_end > before);
}

TEST_CASE("threaded executor: the bound on jobs in flight and duplicate ids are enforced") {
  const TileStore store = TileStore::open(test::small_store());
  FaultConfig slow;
  slow.slow_rate = 1.0;
  slow.slow_ms = 200;
  ThreadedExecutor ex(store, exec_cfg(1, 1, 3, slow));
  ex.submit(test::tile_job(store, 1, TileKey(0, 0, 0, 0)));
  CHECK_THROWS_AS(ex.submit(test::tile_job(store, 1, TileKey(0, 0, 1, 0))), std::logic_error);
  ex.submit(test::tile_job(store, 2, TileKey(0, 0, 1, 0)));
  ex.submit(test::tile_job(store, 3, TileKey(0, 0, 2, 0)));
  CHECK(ex.in_flight() == 3);
  CHECK_THROWS_AS(ex.submit(test::tile_job(store, 4, TileKey(0, 0, 3, 0))), std::logic_error);
  CHECK_THROWS_AS(ex.restart_clock(), std::logic_error);  // jobs in flight
}

TEST_CASE("threaded executor: cancel — queued: dropped for free, and being read: read paid, decode skipped") {
  const TileStore store = TileStore::open(test::small_store());
  FaultConfig slow;
  slow.slow_rate = 1.0;
  slow.slow_ms = 60;
  ThreadedExecutor ex(store, exec_cfg(1, 1, 16, slow));
  const TileKey a(0, 1, 0, 0), b(0, 1, 1, 0), c(0, 1, 2, 0);
  ex.submit(test::tile_job(store, 1, a));
  REQUIRE(eventually([&] { return ex.reads_under_way() == 1; }));
  ex.submit(test::tile_job(store, 2, b));
  ex.submit(test::tile_job(store, 3, c));
  CHECK_FALSE(ex.cancel(1));  // under way: its result still comes, as cancelled
  CHECK(ex.cancel(2));        // queued: gone, no result
  CHECK_FALSE(ex.cancel(2));
  CHECK_FALSE(ex.cancel(42));
  const auto out = collect_all(ex, 2);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  std::vector<JobResult> more;
  ex.collect(ex.now(), more);
  CHECK(more.empty());
  REQUIRE(out.size() == 2);
  CHECK(out[0].id == 1);
  CHECK(out[0].outcome == JobOutcome::cancelled);
  CHECK(out[0].bytes_read == store.locate(a).read_bytes);
  CHECK_FALSE(out[0].data);
  CHECK(out[1].id == 3);
  CHECK(out[1].outcome == JobOutcome::ready);
  CHECK(ex.in_flight() == 0);
}

TEST_CASE("threaded executor: cancelling everything at random moments keeps the contract (one result unless cancel was true)") {
  const TileStore store = TileStore::open(test::small_store());
  const auto keys = test::all_keys(store);
  for (int round = 0; round < 5; ++round) {
    ThreadedExecutor ex(store, exec_cfg(2, 1, 1024));
    const std::size_t n = 200;
    for (std::size_t i = 0; i < n; ++i) ex.submit(test::tile_job(store, i + 1, keys[(i * 7 + static_cast<std::size_t>(round)) % keys.size()]));
    std::this_thread::sleep_for(std::chrono::microseconds(300 * round));
    std::set<RequestId> dropped;
    for (RequestId id = 1; id <= n; ++id)
      if (ex.cancel(id)) dropped.insert(id);
    std::vector<JobResult> out;
    REQUIRE(eventually([&] {
      ex.collect(ex.now(), out);
      return out.size() + dropped.size() == n;
    }));
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    ex.collect(ex.now(), out);
    CHECK(out.size() + dropped.size() == n);
    std::set<RequestId> got;
    for (const auto& r : out) {
      CHECK(got.insert(r.id).second);   // at most one result per job
      CHECK(dropped.count(r.id) == 0);  // none for a job whose cancel returned true
      CHECK(r.outcome != JobOutcome::failed);
      if (r.outcome == JobOutcome::ready) CHECK(r.data);
      if (r.outcome == JobOutcome::cancelled) CHECK(r.bytes_read > 0);  // cancelled after its read started
    }
    CHECK(ex.in_flight() == 0);
  }
}

TEST_CASE("threaded executor: shutdown with work in flight is prompt and leaves one result per job") {
  const TileStore store = TileStore::open(test::small_store());
  FaultConfig slow;
  slow.slow_rate = 1.0;
  slow.slow_ms = 3000;  // reads "take" 3 s each: shutdown must not wait for them
  ThreadedExecutor ex(store, exec_cfg(2, 1, 64, slow));
  const auto keys = test::all_keys(store);
  for (std::size_t i = 0; i < 40; ++i) ex.submit(test::tile_job(store, i + 1, keys[i]));
  REQUIRE(eventually([&] { return ex.reads_under_way() == 2; }));
  const auto t0 = std::chrono::steady_clock::now();
  ex.shutdown();
  CHECK(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < 2.5);
  CHECK(ex.state() == ThreadedExecutor::State::stopped);
  std::vector<JobResult> out;
  ex.collect(ex.now(), out);
  REQUIRE(out.size() == 40);
  std::set<RequestId> ids;
  int read = 0;
  for (const auto& r : out) {
    ids.insert(r.id);
    CHECK(r.outcome == JobOutcome::cancelled);
    read += r.bytes_read > 0;
  }
  CHECK(ids.size() == 40);
  CHECK(read == 2);  // only the two under way touched the disk
  CHECK_THROWS_AS(ex.submit(test::tile_job(store, 99, keys[0])), std::logic_error);
  ex.shutdown();  // idempotent
}

TEST_CASE("threaded executor: destroyed with reads and decodes under way, no thread or descriptor outlives it") {
  const TileStore store = TileStore::open(test::small_store());
  const auto keys = test::all_keys(store);
  const auto count = [](const char* dir) {
    return std::distance(std::filesystem::directory_iterator(dir), std::filesystem::directory_iterator{});
  };
  const auto threads0 = count("/proc/self/task"), fds0 = count("/proc/self/fd");
  for (int i = 0; i < 3; ++i) {
    ThreadedExecutor ex(store, exec_cfg(4, 2, 1024));
    CHECK(count("/proc/self/task") == threads0 + 6);
    for (std::size_t k = 0; k < keys.size(); ++k) ex.submit(test::tile_job(store, k + 1, keys[k]));
    std::this_thread::sleep_for(std::chrono::milliseconds(i));
  }  // the destructor shuts down with work in flight
  CHECK(count("/proc/self/task") == threads0);
  CHECK(count("/proc/self/fd") == fds0);
}

TEST_SUITE_END();
