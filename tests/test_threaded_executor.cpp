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
#include <atomic>
#include <condition_variable>
#include <mutex>
#include <set>
#include <thread>

#include "real_test_util.h"
#include "stream/exec/threaded_executor.h"
#include "core/tile_data.h"
#include "stream/exec/i_producer.h"

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

namespace {

// A fake producer: a 4-channel tile of `side` texels whose bytes are the key's x; optionally waits
// at a gate (the test opens it) and throws for x == 99. Counts its calls.
class GateProducer final : public ITileProducer {
 public:
  explicit GateProducer(bool gated) : open_(!gated) {}
  void produce(const TileJob& job, TileData& out) override {
    {
      std::unique_lock lock(m_);
      ++started_;
      cv_.notify_all();
      cv_.wait(lock, [&] { return open_; });
    }
    calls_.fetch_add(1);
    if (job.key.x() == 99) throw std::runtime_error("brush missing");
    out.side = 8;
    out.channels = 4;
    out.bytes = 8 * 8 * 4;
    out.texels = std::make_unique<std::uint8_t[]>(out.bytes);
    std::fill_n(out.texels.get(), out.bytes, static_cast<std::uint8_t>(job.key.x()));
  }
  void open() {
    std::lock_guard lock(m_);
    open_ = true;
    cv_.notify_all();
  }
  bool wait_started(int n) {
    std::unique_lock lock(m_);
    return cv_.wait_for(lock, std::chrono::seconds(10), [&] { return started_ >= n; });
  }
  int calls() const { return calls_.load(); }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  bool open_;
  int started_ = 0;
  std::atomic<int> calls_{0};
};

TileJob produced_job(RequestId id, std::int64_t x, std::uint64_t prio = 0) {
  TileJob j{id, TileKey(0, 0, x, 0), 0, 8 * 8 * 4, prio};
  j.produce = ProduceWork{64, 4, 0};
  return j;
}

}  // namespace

TEST_CASE("threaded executor: produced tiles are rendered by the producer, never read, beside read tiles") {
  const TileStore store = TileStore::open(test::small_store());
  GateProducer prod(false);
  ThreadedExecutorConfig c = exec_cfg(2, 1, 1024);
  c.producer = &prod;
  c.produce_workers = 2;
  ThreadedExecutor ex(store, c);
  const auto keys = test::all_keys(store);
  const std::size_t reads = std::min<std::size_t>(keys.size(), 8);
  for (std::size_t i = 0; i < reads; ++i) ex.submit(test::tile_job(store, i + 1, keys[i]));
  for (int i = 0; i < 6; ++i) ex.submit(produced_job(100 + static_cast<RequestId>(i), i + 1, static_cast<std::uint64_t>(i)));
  const auto out = collect_all(ex, reads + 6);
  REQUIRE(out.size() == reads + 6);
  int produced = 0;
  for (const JobResult& r : out) {
    REQUIRE(r.outcome == JobOutcome::ready);
    if (r.id < 100) continue;
    ++produced;
    CHECK(r.bytes_read == 0);
    CHECK(r.read_start == r.submitted);
    CHECK(r.read_end == r.submitted);
    CHECK(r.submitted <= r.decode_start);
    CHECK(r.decode_start <= r.decode_end);
    REQUIRE(r.data);
    CHECK(r.data->key == r.key);
    CHECK(r.data->bytes == 256u);
    CHECK(r.data->texels[255] == static_cast<std::uint8_t>(r.key.x()));
  }
  CHECK(produced == 6);
  CHECK(prod.calls() == 6);
}

TEST_CASE("threaded executor: a produced tile cancelled before it starts is dropped, one being produced finishes ready") {
  const TileStore store = TileStore::open(test::small_store());
  GateProducer prod(true);
  ThreadedExecutorConfig c = exec_cfg(1, 1, 64);
  c.producer = &prod;
  c.produce_workers = 1;
  ThreadedExecutor ex(store, c);
  ex.submit(produced_job(1, 1, 0));
  REQUIRE(prod.wait_started(1));  // job 1 is being produced; 2 and 3 queued behind it
  ex.submit(produced_job(2, 2, 1));
  ex.submit(produced_job(3, 3, 2));
  CHECK(ex.cancel(2));        // queued: dropped, no result
  CHECK_FALSE(ex.cancel(1));  // under way: its result still comes
  CHECK_FALSE(ex.cancel(2));  // gone
  prod.open();
  const auto out = collect_all(ex, 2);
  REQUIRE(out.size() == 2);
  std::set<RequestId> ids;
  for (const JobResult& r : out) {
    ids.insert(r.id);
    CHECK(r.outcome == JobOutcome::ready);
  }
  CHECK(ids == std::set<RequestId>{1, 3});
  CHECK(prod.calls() == 2);
  std::vector<JobResult> more;
  ex.shutdown();
  ex.collect(ex.now(), more);
  CHECK(more.empty());
}

TEST_CASE("threaded executor: without a producer a produced tile is refused, a throwing producer fails the job") {
  const TileStore store = TileStore::open(test::small_store());
  {
    ThreadedExecutor ex(store, exec_cfg(1, 1, 8));
    CHECK_THROWS_WITH_AS(ex.submit(produced_job(1, 1)), doctest::Contains("has no producer"), std::logic_error);
    CHECK(ex.in_flight() == 0);
  }
  GateProducer prod(false);
  ThreadedExecutorConfig c = exec_cfg(1, 1, 8);
  c.producer = &prod;
  c.produce_workers = 1;
  ThreadedExecutor ex(store, c);
  ex.submit(produced_job(1, 99));
  const auto out = collect_all(ex, 1);
  REQUIRE(out.size() == 1);
  CHECK(out[0].outcome == JobOutcome::failed);
  CHECK(out[0].fault == Fault::decode_error);
  REQUIRE(ex.fault_examples().size() == 1);
  CHECK(ex.fault_examples()[0].find("brush missing") != std::string::npos);
}

TEST_CASE("threaded executor: shutdown with productions queued and under way leaves one result per job") {
  const TileStore store = TileStore::open(test::small_store());
  GateProducer prod(true);
  ThreadedExecutorConfig c = exec_cfg(1, 1, 64);
  c.producer = &prod;
  c.produce_workers = 1;
  ThreadedExecutor ex(store, c);
  for (RequestId i = 1; i <= 5; ++i) ex.submit(produced_job(i, static_cast<std::int64_t>(i), i));
  REQUIRE(prod.wait_started(1));
  std::thread stopper([&] { ex.shutdown(); });
  REQUIRE(eventually([&] { return ex.state() != ThreadedExecutor::State::running; }));
  prod.open();
  stopper.join();
  CHECK(ex.state() == ThreadedExecutor::State::stopped);
  std::vector<JobResult> out;
  ex.collect(ex.now(), out);
  REQUIRE(out.size() == 5);
  std::set<RequestId> ids;
  for (const JobResult& r : out) ids.insert(r.id);
  CHECK(ids.size() == 5);
  CHECK(std::any_of(out.begin(), out.end(), [](const JobResult& r) { return r.id == 1 && r.outcome == JobOutcome::ready; }));
}

TEST_SUITE_END();
