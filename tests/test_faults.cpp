// Faults (issue 6): every injected kind (EIO, short read, corrupted payload, slow) in both
// clocks, deterministic per tile and attempt; real ones — a store truncated under a running
// executor, a corrupted record, a record that passes its checksum but does not decode, a tile
// outside the store; and corrupt stores given to the real clock are clear errors naming the field.
#include <doctest/doctest.h>

#include <filesystem>

#include "real_test_util.h"
#include "stream/exec/sim_executor.h"
#include "stream/exec/threaded_executor.h"
#include "core/tile_data.h"

// Threaded code: also run by the TSan variant of scripts/test.sh (ctest -L threads).
TEST_SUITE_BEGIN("threads");

using namespace vtsim;
using vtsim::test::eventually;

namespace {

std::vector<JobResult> run_jobs(const TileStore& store, const FaultConfig& f, const std::vector<TileKey>& keys,
                                IoEngine engine = IoEngine::psync) {
  ThreadedExecutorConfig c;
  c.io_engine = engine;
  c.queue_depth = 4;
  c.io_threads = 2;
  c.decode_workers = 1;
  c.capacity = 4096;
  c.faults = f;
  ThreadedExecutor ex(store, c);
  for (std::size_t i = 0; i < keys.size(); ++i) ex.submit(test::tile_job(store, i + 1, keys[i]));
  std::vector<JobResult> out;
  REQUIRE(eventually([&] {
    ex.collect(ex.now(), out);
    return out.size() == keys.size();
  }));
  return out;
}

std::vector<TileKey> some_keys(const TileStore& s, std::size_t n) {
  auto k = test::all_keys(s);
  k.resize(std::min(n, k.size()));
  return k;
}

// Sets the index entry of `k` (checksum field) and re-seals index and header checksums.
void reseal(std::vector<std::uint8_t>& b, const TileStore& s, TileKey k, std::uint64_t record_checksum) {
  using namespace store;
  const std::uint64_t io = load_u64(&b[hdr::index_offset]), ib = load_u64(&b[hdr::index_bytes]);
  store_u64(&b[io + kIndexEntryBytes * s.geometry().slot(k) + ent::checksum], record_checksum);
  store_u64(&b[hdr::index_checksum], checksum64(&b[io], ib));
  const std::uint32_t hb = load_u32(&b[hdr::header_bytes]);
  store_u64(&b[hdr::header_checksum], 0);
  store_u64(&b[hdr::header_checksum], checksum64(b.data(), hb));
}

}  // namespace

TEST_CASE("fault plans: deterministic per (seed, tile, attempt), rates honoured, retries draw afresh") {
  FaultConfig c;
  c.io_error_rate = 0.2;
  c.short_read_rate = 0.1;
  c.checksum_rate = 0.1;
  c.slow_rate = 0.3;
  c.slow_ms = 7;
  c.seed = 11;
  int eio = 0, shortr = 0, sum = 0, slow = 0, recovered = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const TileKey k(static_cast<std::uint32_t>(i % 3), static_cast<std::uint32_t>(i % 9), i, i / 7);
    const FaultPlan p = plan_faults(c, k, 0);
    const FaultPlan again = plan_faults(c, k, 0);
    CHECK(p.fault == again.fault);
    CHECK(p.delay == again.delay);
    eio += p.fault == Fault::io_error;
    shortr += p.fault == Fault::short_read;
    sum += p.fault == Fault::checksum;
    slow += p.delay > 0;
    if (p.delay > 0) CHECK(p.delay == 7'000'000);
    if (p.fault == Fault::io_error && plan_faults(c, k, 1).fault == Fault::none) ++recovered;
  }
  // Precedence: EIO 0.2; short read 0.8 * 0.1; checksum 0.8 * 0.9 * 0.1; slow independent 0.3.
  CHECK(eio == doctest::Approx(0.2 * n).epsilon(0.08));
  CHECK(shortr == doctest::Approx(0.08 * n).epsilon(0.1));
  CHECK(sum == doctest::Approx(0.072 * n).epsilon(0.1));
  CHECK(slow == doctest::Approx(0.3 * n).epsilon(0.08));
  CHECK(recovered > eio / 2);  // a retry is a new draw: most failed tiles read fine the second time
  FaultConfig other = c;
  other.seed = 12;
  int differ = 0;
  for (int i = 0; i < 1000; ++i) differ += plan_faults(c, TileKey(0, 0, i, 0), 0).fault != plan_faults(other, TileKey(0, 0, i, 0), 0).fault;
  CHECK(differ > 100);
  CHECK_FALSE(FaultConfig{}.any());
  FaultLayer none;
  CHECK(none.next(TileKey(0, 0, 1, 1)).fault == Fault::none);
}

TEST_CASE("fault layer: counts attempts per tile, so the n-th read of a tile gets plan n") {
  FaultConfig c;
  c.io_error_rate = 0.5;
  c.seed = 3;
  FaultLayer layer(c);
  const TileKey k(1, 2, 3, 4);
  for (std::uint32_t a = 0; a < 20; ++a) CHECK(layer.next(k).fault == plan_faults(c, k, a).fault);
  std::uint64_t expected = 0;
  for (std::uint32_t a = 0; a < 20; ++a) expected += plan_faults(c, k, a).fault == Fault::io_error;
  CHECK(layer.injected().io_error == expected);
}

TEST_CASE("injected EIO: every read fails as io_error with nothing read, naming the tile") {
  const TileStore store = TileStore::open(test::small_store());
  FaultConfig f;
  f.io_error_rate = 1.0;
  for (const IoEngine engine : test::io_engines_here())
  for (const JobResult& r : run_jobs(store, f, some_keys(store, 30), engine)) {
    CHECK(r.outcome == JobOutcome::failed);
    CHECK(r.fault == Fault::io_error);
    CHECK(r.bytes_read == 0);
    CHECK_FALSE(r.data);
  }
}

TEST_CASE("injected short reads: every read fails as short_read") {
  const TileStore store = TileStore::open(test::small_store());
  FaultConfig f;
  f.short_read_rate = 1.0;
  for (const IoEngine engine : test::io_engines_here())
  for (const JobResult& r : run_jobs(store, f, some_keys(store, 30), engine)) {
    CHECK(r.outcome == JobOutcome::failed);
    CHECK(r.fault == Fault::short_read);
    CHECK(r.bytes_read < store.locate(r.key).stored_bytes);
  }
}

TEST_CASE("injected corruption: every record fails its checksum, nothing corrupt reaches RAM") {
  const TileStore store = TileStore::open(test::small_store());
  FaultConfig f;
  f.checksum_rate = 1.0;
  for (const IoEngine engine : test::io_engines_here())
  for (const JobResult& r : run_jobs(store, f, some_keys(store, 30), engine)) {
    CHECK(r.outcome == JobOutcome::failed);
    CHECK(r.fault == Fault::checksum);
    CHECK(r.bytes_read == store.locate(r.key).read_bytes);  // the read happened; its bytes were bad
    CHECK_FALSE(r.data);
  }
}

TEST_CASE("injected slow reads: the tile arrives, late") {
  const TileStore store = TileStore::open(test::small_store());
  FaultConfig f;
  f.slow_rate = 1.0;
  f.slow_ms = 30;
  for (const IoEngine engine : test::io_engines_here())
  for (const JobResult& r : run_jobs(store, f, some_keys(store, 6), engine)) {
    CHECK(r.outcome == JobOutcome::ready);
    CHECK(r.read_end - r.read_start >= 30'000'000);
    CHECK(r.data);
  }
}

TEST_CASE("injected faults in the simulated clock: the same kinds, at the same stages") {
  auto one = [](FaultConfig f) {
    SimExecutor ex(DiskModel{100.0, 100.0, 1}, DecodeModel{1.0, 0.0, 1}, 8, f);
    ex.submit(TileJob{1, TileKey(0, 0, 1, 1), 10'000, 40'000, 0});
    std::vector<JobResult> out;
    ex.collect(10'000'000'000, out);
    REQUIRE(out.size() == 1);
    return out[0];
  };
  FaultConfig f;
  f.io_error_rate = 1.0;
  JobResult r = one(f);
  CHECK(r.fault == Fault::io_error);
  CHECK(r.bytes_read == 0);
  CHECK(r.decode_end == 100'000 + 100'000);  // failed when the transfer ended: 100 us + 10 kB at 100 MB/s
  f = {};
  f.short_read_rate = 1.0;
  r = one(f);
  CHECK(r.fault == Fault::short_read);
  CHECK(r.bytes_read == 5'000);
  f = {};
  f.checksum_rate = 1.0;
  r = one(f);
  CHECK(r.fault == Fault::checksum);
  CHECK(r.outcome == JobOutcome::failed);
  CHECK(r.decode_end == 100'000 + 100'000 + 40'000'000);  // found after the decode (40 kB at 1 MB/s)
  f = {};
  f.slow_rate = 1.0;
  f.slow_ms = 3;
  r = one(f);
  CHECK(r.outcome == JobOutcome::ready);
  CHECK(r.read_end == 100'000 + 3'000'000 + 100'000);
}

TEST_CASE("a store truncated under a running executor: the lost records fail as short reads, the rest decode") {
  test::RealScratch dir;
  const std::string p = dir.file("trunc.vts");
  std::filesystem::copy_file(test::small_store(), p);
  for (const IoEngine engine : test::io_engines_here()) {
  CAPTURE(engine_name(engine));
  const TileStore store = TileStore::open(p);  // the whole file: copied again for each engine
  ThreadedExecutorConfig c;
  c.io_threads = 2;
  c.io_engine = engine;
  c.queue_depth = 4;
  c.capacity = 4096;
  ThreadedExecutor ex(store, c);
  const std::uint64_t cut = store.header().data_offset + (store.header().file_bytes - store.header().data_offset) / 2;
  std::filesystem::resize_file(p, cut);
  const auto keys = test::all_keys(store);
  for (std::size_t i = 0; i < keys.size(); ++i) ex.submit(test::tile_job(store, i + 1, keys[i]));
  std::vector<JobResult> out;
  REQUIRE(eventually([&] {
    ex.collect(ex.now(), out);
    return out.size() == keys.size();
  }));
  int lost = 0, fine = 0;
  for (const JobResult& r : out) {
    const TileLocation loc = store.locate(r.key);
    if (loc.offset + loc.stored_bytes <= cut) {
      CHECK(r.outcome == JobOutcome::ready);
      ++fine;
    } else {
      CHECK(r.outcome == JobOutcome::failed);
      CHECK(r.fault == Fault::short_read);
      ++lost;
    }
  }
  CHECK(lost > 100);
  CHECK(fine > 100);
  const auto ex_msgs = ex.fault_examples();
  REQUIRE(ex_msgs.size() == 1);
  CHECK(ex_msgs[0].find("short read") != std::string::npos);
  CHECK(ex_msgs[0].find("file truncated?") != std::string::npos);
  CHECK(ex_msgs[0].find("tile (") != std::string::npos);
  ex.shutdown();
  std::filesystem::remove(p);
  std::filesystem::copy_file(test::small_store(), p);
  }
}

TEST_CASE("a record corrupted on disk fails its checksum, and one that passes its checksum but does not decode is a decode error") {
  test::RealScratch dir;
  const std::string p = dir.file("bad.vts");
  auto bytes = test::file_bytes(test::small_store());
  const TileStore orig = TileStore::open(test::small_store());
  const TileKey flipped(0, 0, 2, 3), garbage(0, 0, 4, 1), fine(1, 0, 2, 3);
  // The tile the executor's workers warm up on (io_pool.h, decode_pool.h): corrupt too, it must
  // neither stop the executor from starting nor be reported by anything but its own request.
  const TileKey warm(0, orig.geometry().levels - 1, 0, 0);
  const TileLocation lf = orig.locate(flipped), lg = orig.locate(garbage);
  REQUIRE(orig.index()[orig.geometry().slot(garbage)].codec == store::CodecId::zstd);
  bytes[lf.offset + 10] ^= 0xFF;  // a bit flip on disk
  bytes[orig.locate(warm).offset + 10] ^= 0xFF;
  for (std::uint32_t i = 0; i < lg.stored_bytes; ++i) bytes[lg.offset + i] = static_cast<std::uint8_t>(i * 37);  // not zstd
  reseal(bytes, orig, garbage, store::checksum64(&bytes[lg.offset], lg.stored_bytes));  // ... with a valid checksum
  test::put_file(p, bytes);
  const TileStore store = TileStore::open(p);
  const auto out = run_jobs(store, {}, {flipped, garbage, fine, warm});
  REQUIRE(out.size() == 4);
  for (const JobResult& r : out) {
    if (r.key == flipped || r.key == warm) CHECK(r.fault == Fault::checksum);
    if (r.key == garbage) CHECK(r.fault == Fault::decode_error);
    if (r.key == fine) CHECK(r.outcome == JobOutcome::ready);
  }
}

TEST_CASE("a tile outside the store is a bad_record result, not a crash") {
  const TileStore store = TileStore::open(test::small_store());
  ThreadedExecutorConfig c;
  ThreadedExecutor ex(store, c);
  ex.submit(TileJob{1, TileKey(0, 0, 4000, 0), 4096, 4096, 0});
  ex.submit(TileJob{2, TileKey(3, 0, 0, 0), 4096, 4096, 0});
  std::vector<JobResult> out;
  REQUIRE(eventually([&] {
    ex.collect(ex.now(), out);
    return out.size() == 2;
  }));
  for (const auto& r : out) CHECK(r.fault == Fault::bad_record);
}

TEST_CASE("corrupt stores given to the real clock are clear errors naming the field (exit 2), never a crash") {
  test::RealScratch dir;
  REQUIRE(test::run_cli(dir, "trace gen static --duration 0.2 -o " + dir.file("t.csv")).code == 0);
  const auto good = test::file_bytes(test::small_store());
  struct Case {
    const char* name;
    std::function<void(std::vector<std::uint8_t>&)> damage;
    const char* expect;
  };
  const std::vector<Case> cases = {
      {"bad magic", [](auto& b) { b[0] = 'X'; }, "field 'magic'"},
      {"wrong version", [](auto& b) { store::store_u32(&b[store::hdr::version_major], 2); }, "field 'version_major'"},
      {"truncated", [](auto& b) { b.erase(b.end() - 8192, b.end()); }, "truncated"},
      {"offset past the end",
       [&](auto& b) {
         const TileStore s = TileStore::open(test::small_store());
         const std::uint64_t io = store::load_u64(&b[store::hdr::index_offset]);
         store::store_u64(&b[io + 5 * store::kIndexEntryBytes + store::ent::offset], b.size() + 4096);
         reseal(b, s, s.geometry().key_of_slot(5), store::load_u64(&b[io + 5 * store::kIndexEntryBytes + store::ent::checksum]));
       },
       "field 'offset'"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.name);
    auto b = good;
    c.damage(b);
    const std::string p = dir.file("bad.vts");
    test::put_file(p, b);
    const auto r = test::run_cli(dir, "replay --clock real --store " + p + " --trace " + dir.file("t.csv") +
                                          " --set texture.texels_per_m=32 -q");
    CHECK(r.code == 2);
    CHECK(r.err.find(c.expect) != std::string::npos);
    CHECK(r.err.find("bad.vts") != std::string::npos);
  }
}

TEST_SUITE_END();
