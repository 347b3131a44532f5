// The IO thread pool (src/stream/exec/io_pool.h): O_DIRECT alignment and fallback, correct bytes,
// priority order, cancellation, the bound on reads in flight, stop with reads under way.
#include <doctest/doctest.h>

#include <atomic>
#include <mutex>

#include "core/error.h"
#include "real_test_util.h"
#include "stream/exec/decode_pool.h"
#include "stream/exec/io_pool.h"

// Threaded code: also run by the TSan variant of scripts/test.sh (ctest -L threads).
TEST_SUITE_BEGIN("threads");

using namespace vtsim;
using vtsim::test::eventually;

namespace {

// Collects results from the pool's workers.
struct Sink {
  std::mutex m;
  std::vector<ReadResult> results;
  void operator()(ReadResult&& r) {
    std::lock_guard lock(m);
    results.push_back(std::move(r));
  }
  std::size_t size() {
    std::lock_guard lock(m);
    return results.size();
  }
};

}  // namespace

TEST_CASE("direct_io_aligned: buffer address, offset and size must all be multiples of 4096") {
  AlignedBuffer b(3 * 4096);
  CHECK(direct_io_aligned(b.data(), 0, 4096));
  CHECK(direct_io_aligned(b.data() + 4096, 8192, 2 * 4096));
  CHECK_FALSE(direct_io_aligned(b.data() + 512, 0, 4096));
  CHECK_FALSE(direct_io_aligned(b.data(), 512, 4096));
  CHECK_FALSE(direct_io_aligned(b.data(), 4096, 4096 + 512));
}

TEST_CASE("io pool: every record read with aligned buffers, offsets and sizes, byte for byte the file's") {
  const TileStore store = TileStore::open(test::small_store());
  const auto file = test::file_bytes(store.path());
  for (const IoEngine engine : test::io_engines_here()) {
  CAPTURE(engine_name(engine));
  WallClock clock;
  Sink sink;
  IoPool pool(store, test::pool_config(engine, 3, 4), clock, std::ref(sink));
  CHECK(pool.engine() == engine);
  CHECK(pool.engine_warning().empty());  // io_uring works here, registered buffers included
  // O_DIRECT is checked once at open: either on, or off with the reason.
  CHECK((pool.direct() || !pool.warning().empty()));
  MESSAGE("O_DIRECT " << (pool.direct() ? "on" : "off: " + pool.warning()));
  const auto keys = test::all_keys(store);
  for (std::size_t i = 0; i < keys.size(); ++i) REQUIRE(pool.submit(ReadRequest{i + 1, keys[i], i % 7}));
  REQUIRE(eventually([&] { return sink.size() == keys.size(); }));
  for (const ReadResult& r : sink.results) {
    const TileLocation loc = store.locate(r.key);
    REQUIRE(r.fault == Fault::none);
    CHECK(r.key == keys[r.id - 1]);
    CHECK(direct_io_aligned(r.record.data(), loc.offset, r.bytes_read));
    CHECK(r.bytes_read == loc.read_bytes);
    CHECK(r.stored_bytes == loc.stored_bytes);
    CHECK(r.read_start <= r.read_end);
    CHECK(std::equal(r.record.data(), r.record.data() + r.bytes_read, file.begin() + static_cast<std::ptrdiff_t>(loc.offset)));
  }
  // io_uring reads land in each worker's registered arena (while it has a free slot).
  if (engine == IoEngine::io_uring)
    CHECK(std::any_of(sink.results.begin(), sink.results.end(), [](const ReadResult& r) { return r.record.in_arena(); }));
  CHECK(pool.stop().empty());
  CHECK(pool.state() == IoPool::State::stopped);
  }
}

TEST_CASE("io pool: buffered reads when O_DIRECT is not wanted (the fallback path) are the same bytes") {
  const TileStore store = TileStore::open(test::small_store());
  for (const IoEngine engine : test::io_engines_here()) {
  CAPTURE(engine_name(engine));
  WallClock clock;
  Sink sink;
  IoPool pool(store, test::pool_config(engine, 1, 2, /*direct=*/false), clock, std::ref(sink));
  CHECK_FALSE(pool.direct());
  CHECK(pool.warning().empty());  // not refused: not asked for
  const TileKey k(1, 2, 3, 1);
  REQUIRE(pool.submit(ReadRequest{1, k, 0}));
  REQUIRE(eventually([&] { return sink.size() == 1; }));
  const auto file = test::file_bytes(store.path());
  const TileLocation loc = store.locate(k);
  CHECK(sink.results[0].fault == Fault::none);
  CHECK(std::equal(sink.results[0].record.data(), sink.results[0].record.data() + loc.stored_bytes,
                   file.begin() + static_cast<std::ptrdiff_t>(loc.offset)));
  }
}

TEST_CASE("O_DIRECT fallback: a filesystem that refuses O_DIRECT gives buffered reads and a warning") {
  // procfs refuses O_DIRECT at open (EINVAL), as tmpfs did before Linux 6.6: the pool's open policy
  // (open_for_read) must fall back to the page cache and say why.
  const DirectOpen o = open_for_read("/proc/version", true);
  CHECK_FALSE(o.file.direct());
  CHECK(o.warning.find("/proc/version") != std::string::npos);
  CHECK(o.warning.find("page cache") != std::string::npos);
  AlignedBuffer b(4096);
  CHECK(o.file.pread_full(b.data(), 4096, 0) > 5);
  CHECK(std::string(reinterpret_cast<const char*>(b.data()), 5) == "Linux");
  // Not asked for: no warning.
  CHECK(open_for_read("/proc/version", false).warning.empty());
}

TEST_CASE("io pool: verify checks the checksum on the IO worker, verify = false hands the bytes on for the decode stage") {
  const TileStore store = TileStore::open(test::small_store());
  FaultConfig fc;
  fc.checksum_rate = 1.0;  // every payload gets a flipped byte after the read
  for (const IoEngine engine : test::io_engines_here())
  for (const bool verify : {true, false}) {
    CAPTURE(engine_name(engine));
    CAPTURE(verify);
    WallClock clock;
    Sink sink;
    FaultLayer faults(fc);
    IoPool pool(store, test::pool_config(engine, 1, 2, true, verify), clock, std::ref(sink), &faults);
    const TileKey k(0, 0, 1, 1);
    REQUIRE(pool.submit(ReadRequest{1, k, 0}));
    REQUIRE(eventually([&] { return sink.size() == 1; }));
    const ReadResult& r = sink.results[0];
    CHECK(r.fault == (verify ? Fault::checksum : Fault::none));
    CHECK(r.bytes_read == store.locate(k).read_bytes);
    if (!verify) {  // the decode stage's check still catches it
      const DecodeResult d = decode_record(store, k, r.record.data(), r.bytes_read, /*verify=*/true);
      CHECK(d.fault == Fault::checksum);
      CHECK_FALSE(d.data);
    }
  }
}

TEST_CASE("io pool: queued requests are served by priority, then submission order") {
  const TileStore store = TileStore::open(test::small_store());
  // One read in flight (io_uring at depth 1), so the queue fills while the first one is read.
  for (const IoEngine engine : test::io_engines_here()) {
  CAPTURE(engine_name(engine));
  WallClock clock;
  Sink sink;
  FaultConfig fc;
  fc.slow_rate = 1.0;  // every read takes 40 ms: the queue fills while the first one is read
  fc.slow_ms = 40;
  FaultLayer faults(fc);
  IoPool pool(store, test::pool_config(engine, 1), clock, std::ref(sink), &faults);
  REQUIRE(pool.submit(ReadRequest{1, TileKey(0, 0, 0, 0), 0}));
  REQUIRE(eventually([&] { return pool.active() == 1; }));
  REQUIRE(pool.submit(ReadRequest{2, TileKey(0, 0, 1, 0), 5}));
  REQUIRE(pool.submit(ReadRequest{3, TileKey(0, 0, 2, 0), 1}));
  REQUIRE(pool.submit(ReadRequest{4, TileKey(0, 0, 3, 0), 5}));
  REQUIRE(pool.submit(ReadRequest{5, TileKey(0, 0, 4, 0), 3}));
  CHECK_FALSE(pool.submit(ReadRequest{5, TileKey(0, 0, 4, 0), 3}));  // already queued
  REQUIRE(eventually([&] { return sink.size() == 5; }));
  std::vector<RequestId> order;
  for (const auto& r : sink.results) order.push_back(r.id);
  CHECK(order == std::vector<RequestId>{1, 3, 5, 2, 4});
  }
}

TEST_CASE("io pool: cancel drops queued requests (no read, no result) and not the one under way") {
  const TileStore store = TileStore::open(test::small_store());
  for (const IoEngine engine : test::io_engines_here()) {
  CAPTURE(engine_name(engine));
  WallClock clock;
  Sink sink;
  FaultConfig fc;
  fc.slow_rate = 1.0;
  fc.slow_ms = 30;
  FaultLayer faults(fc);
  IoPool pool(store, test::pool_config(engine, 1), clock, std::ref(sink), &faults);
  REQUIRE(pool.submit(ReadRequest{1, TileKey(0, 0, 0, 0), 0}));
  REQUIRE(eventually([&] { return pool.active() == 1; }));
  for (RequestId id = 2; id <= 5; ++id) REQUIRE(pool.submit(ReadRequest{id, TileKey(0, 0, static_cast<std::int64_t>(id), 0), 0}));
  CHECK_FALSE(pool.cancel(1));  // being read
  CHECK(pool.cancel(3));
  CHECK(pool.cancel(4));
  CHECK_FALSE(pool.cancel(4));   // already gone
  CHECK_FALSE(pool.cancel(99));  // never submitted
  REQUIRE(eventually([&] { return sink.size() == 3; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  CHECK(sink.size() == 3);
  std::vector<RequestId> ids;
  for (const auto& r : sink.results) ids.push_back(r.id);
  CHECK(ids == std::vector<RequestId>{1, 2, 5});
  CHECK(faults.injected().slow == 3);  // cancelled requests were never read
  }
}

TEST_CASE("io pool: reads in flight never exceed the thread count (psync) or threads x queue depth (io_uring), and reach it") {
  const TileStore store = TileStore::open(test::small_store());
  for (const IoEngine engine : test::io_engines_here()) {
  CAPTURE(engine_name(engine));
  const int depth = engine == IoEngine::io_uring ? 3 : 1;
  WallClock clock;
  std::atomic<int> max_active{0};
  std::atomic<std::size_t> done{0};
  FaultConfig fc;
  fc.slow_rate = 1.0;
  fc.slow_ms = 5;
  FaultLayer faults(fc);
  IoPool* self = nullptr;
  IoPool pool(store, test::pool_config(engine, 2, depth), clock,
              [&](ReadResult&&) {
                int a = self->active(), m = max_active.load();
                while (a > m && !max_active.compare_exchange_weak(m, a)) {
                }
                done.fetch_add(1);
              },
              &faults);
  self = &pool;
  const auto keys = test::all_keys(store);
  for (std::size_t i = 0; i < 40; ++i) REQUIRE(pool.submit(ReadRequest{i + 1, keys[i], 0}));
  int seen = 0;
  REQUIRE(eventually([&] {
    seen = std::max(seen, pool.active());
    return done.load() == 40;
  }));
  CHECK(max_active.load() <= 2 * depth);
  CHECK(seen <= 2 * depth);
  CHECK(max_active.load() >= 1);
  CHECK(pool.queue_depth() == depth);
  // 40 requests of 5 ms each: a worker fills its ring, so more reads are in flight than threads.
  if (engine == IoEngine::io_uring) CHECK(seen > 2);
  }
}

TEST_CASE("io pool: stop with reads under way returns the queued requests, delivers the rest and joins") {
  const TileStore store = TileStore::open(test::small_store());
  for (const IoEngine engine : test::io_engines_here()) {
  CAPTURE(engine_name(engine));
  WallClock clock;
  Sink sink;
  FaultConfig fc;
  fc.slow_rate = 1.0;
  fc.slow_ms = 5000;  // a read "takes" 5 s: stop must not wait for that
  FaultLayer faults(fc);
  IoPool pool(store, test::pool_config(engine, 2), clock, std::ref(sink), &faults);
  for (RequestId id = 1; id <= 10; ++id) REQUIRE(pool.submit(ReadRequest{id, TileKey(1, 0, static_cast<std::int64_t>(id), 0), id}));
  REQUIRE(eventually([&] { return pool.active() == 2; }));
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<ReadRequest> dropped = pool.stop();
  const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  CHECK(waited < 4.0);  // far less than one slow read
  CHECK(dropped.size() == 8);
  CHECK(sink.size() == 2);  // the two under way finished and reported
  std::vector<RequestId> all;
  for (const auto& q : dropped) all.push_back(q.id);
  for (const auto& r : sink.results) all.push_back(r.id);
  std::sort(all.begin(), all.end());
  CHECK(all == std::vector<RequestId>{1, 2, 3, 4, 5, 6, 7, 8, 9, 10});
  CHECK(pool.state() == IoPool::State::stopped);
  CHECK_FALSE(pool.submit(ReadRequest{11, TileKey(1, 0, 0, 0), 0}));
  CHECK(pool.stop().empty());  // idempotent
  }
}

TEST_CASE("io pool: a key outside the store is a bad_record result naming the tile, not a crash") {
  const TileStore store = TileStore::open(test::small_store());
  for (const IoEngine engine : test::io_engines_here()) {
  CAPTURE(engine_name(engine));
  WallClock clock;
  Sink sink;
  IoPool pool(store, test::pool_config(engine, 1, 4), clock, std::ref(sink));
  REQUIRE(pool.submit(ReadRequest{1, TileKey(0, 0, 500, 0), 0}));
  REQUIRE(pool.submit(ReadRequest{2, TileKey(9, 0, 0, 0), 0}));
  REQUIRE(eventually([&] { return sink.size() == 2; }));
  for (const auto& r : sink.results) {
    CHECK(r.fault == Fault::bad_record);
    CHECK(r.bytes_read == 0);
    CHECK(r.error.find("outside the store") != std::string::npos);
  }
  }
}

TEST_CASE("io pool: warm workers read once each before the constructor returns, with no result and no fault drawn") {
  const TileStore store = TileStore::open(test::small_store());
  WallClock clock;
  Sink sink;
  FaultConfig fc;
  fc.io_error_rate = 1.0;  // every read the fault layer plans fails
  FaultLayer faults(fc);
  IoPool pool(store, IoPoolConfig{3, true, true, /*buffers=*/5, /*warm=*/true}, clock, std::ref(sink), &faults);
  CHECK(pool.warmed() == 3);        // the constructor waited for every worker, each read whole
  CHECK(pool.free_buffers() == 5);  // the reserve, and the warm reads gave theirs back
  if (io_uring_unavailable().empty()) {  // io_uring: each worker warms through its ring; its arena holds its depth and its share of the reserve
    IoPoolConfig c = test::pool_config(IoEngine::io_uring, 3, 2);
    c.buffers = 5;
    c.warm = true;
    Sink ring_sink;
    IoPool ring(store, c, clock, std::ref(ring_sink), &faults);
    CHECK(ring.warmed() == 3);
    CHECK(ring.free_buffers() == 3 * (2 + 2));
    CHECK(ring_sink.size() == 0);
    CHECK(faults.injected().io_error == 0);
  }
  CHECK(sink.size() == 0);
  CHECK(faults.injected().io_error == 0);
  // The warm reads used the coarsest tile; its first real read is still attempt 0 of its plan.
  const TileKey coarsest(0, store.geometry().levels - 1, 0, 0);
  REQUIRE(pool.submit(ReadRequest{1, coarsest, 0}));
  REQUIRE(eventually([&] { return sink.size() == 1; }));
  CHECK(sink.results[0].fault == Fault::io_error);
  CHECK(faults.injected().io_error == 1);

  Sink cold_sink;
  IoPool cold(store, IoPoolConfig{2, true}, clock, std::ref(cold_sink));
  CHECK(cold.warmed() == 0);
  CHECK(cold.free_buffers() == 0);
}

TEST_CASE("decode pool: warm workers decode every layer once before the constructor returns, with no result") {
  const TileStore store = TileStore::open(test::small_store());
  WallClock clock;
  std::atomic<int> results{0};
  DecodePool pool(store, 2, clock, [&](DecodeResult&&) { ++results; }, true, /*warm=*/true);
  CHECK(pool.warmed() == 2);  // both workers decoded both layers
  CHECK(results.load() == 0);
  DecodePool cold(store, 1, clock, [&](DecodeResult&&) { ++results; });
  CHECK(cold.warmed() == 0);

  // A corrupt warm-up tile (layer 1's coarsest): no worker counts as warmed, the constructor
  // still returns, and nothing is reported until a request asks for that tile.
  test::RealScratch dir;
  const std::string p = dir.file("bad.vts");
  auto bytes = test::file_bytes(test::small_store());
  bytes[store.locate(TileKey(1, store.geometry().levels - 1, 0, 0)).offset + 10] ^= 0xFF;
  test::put_file(p, bytes);
  const TileStore bad = TileStore::open(p);
  DecodePool broken(bad, 2, clock, [&](DecodeResult&&) { ++results; }, true, /*warm=*/true);
  CHECK(broken.warmed() == 0);
  CHECK(results.load() == 0);
}

TEST_CASE("io and decode pools: a worker count outside 1..1024 is an InputError naming the config key, warm or not") {
  const TileStore store = TileStore::open(test::small_store());
  WallClock clock;
  Sink sink;
  for (const bool warm : {false, true})
    for (const int n : {0, -3, 1025}) {
      CAPTURE(warm);
      CAPTURE(n);
      CHECK_THROWS_WITH_AS(IoPool(store, IoPoolConfig{n, true, true, 0, warm}, clock, std::ref(sink)),
                           doctest::Contains("io.threads: must be in 1..1024"), InputError);
      CHECK_THROWS_WITH_AS(DecodePool(store, n, clock, [](DecodeResult&&) {}, true, warm),
                           doctest::Contains("decode.workers: must be in 1..1024"), InputError);
    }
}

TEST_SUITE_END();

TEST_CASE("io_uring fallback: a kernel without io_uring or a seccomp that refuses it reads with psync and says why") {
  const TileStore store = TileStore::open(test::small_store());
  const auto file = test::file_bytes(store.path());
  for (const int err : {ENOSYS, EPERM}) {
    CAPTURE(err);
    IoPoolConfig c = test::pool_config(IoEngine::io_uring, 2, 8);
    c.fail_ring_errno = err;
    WallClock clock;
    Sink sink;
    IoPool pool(store, c, clock, std::ref(sink));
    CHECK(pool.engine() == IoEngine::psync);
    CHECK(pool.queue_depth() == 1);
    CHECK(pool.engine_warning().find("io_uring_queue_init failed") != std::string::npos);
    CHECK(pool.engine_warning().find(err == ENOSYS ? "no io_uring" : "seccomp") != std::string::npos);
    CHECK(pool.engine_warning().find("reading with psync") != std::string::npos);
    CHECK(io_uring_unavailable(err) == pool.engine_warning());
    const TileKey k(0, 1, 1, 0);
    REQUIRE(pool.submit(ReadRequest{1, k, 0}));
    REQUIRE(eventually([&] { return sink.size() == 1; }));
    const TileLocation loc = store.locate(k);
    CHECK(sink.results[0].fault == Fault::none);
    CHECK(std::equal(sink.results[0].record.data(), sink.results[0].record.data() + loc.stored_bytes,
                     file.begin() + static_cast<std::ptrdiff_t>(loc.offset)));
  }
  // Where the kernel refuses io_uring the engine tests run on psync only: say so.
  const std::string refused = io_uring_unavailable();
  WARN_MESSAGE(refused.empty(), refused);
}

TEST_CASE("io_uring: a queue depth outside 1..1024 is an InputError naming io.queue_depth") {
  const TileStore store = TileStore::open(test::small_store());
  WallClock clock;
  Sink sink;
  for (const int d : {0, -1, 1025}) {
    CAPTURE(d);
    CHECK_THROWS_WITH_AS(IoPool(store, test::pool_config(IoEngine::io_uring, 1, d), clock, std::ref(sink)),
                         doctest::Contains("io.queue_depth: must be in 1..1024"), InputError);
  }
  // psync ignores the depth (one read per thread).
  IoPool p(store, test::pool_config(IoEngine::psync, 1, 0), clock, std::ref(sink));
  CHECK(p.queue_depth() == 1);
}
