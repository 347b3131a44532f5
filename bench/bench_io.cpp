// Tile reads through the IO pool (src/stream/exec/io_pool.h) against fio on the same file, side by
// side in one run (issue 6): fio's psync engine with O_DIRECT, random reads, the same block size
// (every record of a raw RGB 128² store is 48 KiB, so fio's block-aligned offsets are exactly the
// records), the same thread count, the same number of reads. Targets: bandwidth >= 0.9x fio's,
// p99 read latency within 1.2x of fio's (ratio >= 1/1.2). fio reports its own bandwidth and
// completion-latency percentiles (excluding its start-up); the pool's are measured the same way:
// bytes over first submit .. last completion, and each read's pread time on its worker. The pool
// runs as the threaded executor runs it: checksums are the decode stage's (io_pool.h).
// The io_uring engine (io.engine = io_uring) runs against fio's io_uring engine the same way, at
// iodepth 1, 4, 16 and 32 (one thread; and 4 threads at depth 16), fio with registered buffers
// and file as the pool (--fixedbufs --registerfiles). Targets: >= 0.9x fio at depth 16, p99 within
// 1.2x. docs/real-engine.md and docs/performance.md carry the figures.
#include <stdlib.h>

#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <random>

#include "harness.h"
#include "stream/exec/io_pool.h"
#include "stream/store/store_builder.h"

namespace {

using namespace vtsim;
namespace vb = vtsim::bench;

struct TempDir {
  std::filesystem::path path;
  TempDir() {
    // Next to the build, not /tmp: /tmp may be a tmpfs, and this must hit a disk.
    std::string t = (std::filesystem::current_path() / ".vtsim-bench-io-XXXXXX").string();
    if (!mkdtemp(t.data())) throw std::runtime_error("mkdtemp failed in the current directory");
    path = t;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};

// A raw store (records of exactly 48 KiB) filled with hashed bytes.
void write_raw_store(const std::string& path, std::uint64_t size) {
  StoreSpec spec;
  spec.width = spec.height = size;
  spec.tile = 128;
  spec.border = 0;
  spec.layers = {StoreLayerSpec{"albedo", 3, CodecSpec{store::CodecId::raw, 0}, store::Transfer::srgb}};
  StoreWriter w(path, spec);
  std::vector<std::uint8_t> texels(w.tile_bytes(0));
  for (std::uint64_t s = 0; s < w.geometry().tile_count(); ++s) {
    for (std::size_t i = 0; i < texels.size(); i += 8) {
      const std::uint64_t v = mix64(s * 1000003u + i);
      std::memcpy(&texels[i], &v, std::min<std::size_t>(8, texels.size() - i));
    }
    w.add_tile(w.geometry().key_of_slot(s), texels.data());
  }
  w.commit();
}

struct Rep {
  double MBps = 0, p99_ms = 0, p50_ms = 0;
};

double nearest_rank(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(std::ceil(p * static_cast<double>(v.size())));
  return v[std::min(v.size() - 1, i == 0 ? 0 : i - 1)];
}

struct Case {
  IoEngine engine;
  int threads, depth;
  std::string name() const {
    return engine == IoEngine::psync ? std::string("randread_48k")
                                     : fmt::format("uring_t{}_qd{}", threads, depth);
  }
};

Rep run_pool(const TileStore& store, const Case& c, const std::vector<TileKey>& keys) {
  WallClock clock;
  std::vector<double> lat(keys.size());
  std::atomic<std::size_t> bad{0};
  std::mutex m;
  std::condition_variable cv;
  std::size_t done = 0;
  Ticks t0 = 0, t1 = 0;
  {
    // As the threaded executor runs it: O_DIRECT, and the checksum left to the decode stage
    // (bench_decode measures it there), so both sides do the same work per read.
    IoPoolConfig pc{c.threads, true, /*verify=*/false};
    pc.engine = c.engine;
    pc.queue_depth = c.depth;
    pc.buffers = static_cast<std::size_t>(c.threads * c.depth);
    pc.warm = true;
    IoPool pool(store, pc, clock, [&](ReadResult&& r) {
      if (r.fault != Fault::none || r.bytes_read != 49152) bad.fetch_add(1);
      lat[r.id - 1] = ticks_to_ms(r.read_end - r.read_start);
      std::lock_guard lock(m);
      if (++done == keys.size()) {
        t1 = clock.now();
        cv.notify_one();
      }
    });
    if (!pool.direct()) throw std::runtime_error("O_DIRECT refused here: " + pool.warning());
    if (pool.engine() != c.engine) throw std::runtime_error(pool.engine_warning());
    t0 = clock.now();
    for (std::size_t i = 0; i < keys.size(); ++i) pool.submit(ReadRequest{i + 1, keys[i], 0});
    std::unique_lock lock(m);
    cv.wait(lock, [&] { return done == keys.size(); });
  }
  if (bad.load()) throw std::runtime_error(std::to_string(bad.load()) + " pool reads failed");
  return {static_cast<double>(keys.size()) * 49152.0 / ticks_to_seconds(t1 - t0) / 1e6, nearest_rank(lat, 0.99),
          nearest_rank(lat, 0.50)};
}

Rep run_fio(const TileStore& store, const Case& c, std::size_t reads) {
  const std::uint64_t lo = store.header().data_offset, hi = store.header().file_bytes;
  const std::string engine = c.engine == IoEngine::psync
                                 ? std::string("--ioengine=psync")
                                 : fmt::format("--ioengine=io_uring --iodepth={} --fixedbufs --registerfiles", c.depth);
  const std::string cmd = fmt::format(
      "fio --name=vtsim --filename='{}' --rw=randread --bs=49152 {} --direct=1 --numjobs={} --thread "
      "--group_reporting --offset={} --size={} --number_ios={} --randrepeat=0 --output-format=json 2>/dev/null",
      store.path(), engine, c.threads, lo, hi - lo, reads / static_cast<std::size_t>(c.threads));
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) throw std::runtime_error("cannot run fio");
  std::string out;
  char buf[4096];
  while (std::size_t n = std::fread(buf, 1, sizeof buf, p)) out.append(buf, n);
  const int rc = pclose(p);
  const auto brace = out.find('{');
  if (rc != 0 || brace == std::string::npos)
    throw std::runtime_error("fio failed (exit " + std::to_string(rc) + "); is it installed? (scripts/setup.sh installs it)");
  const auto j = nlohmann::json::parse(out.substr(brace));
  const auto& rd = j["jobs"][0]["read"];
  const auto& pc = rd["clat_ns"]["percentile"];
  return {rd["bw_bytes"].get<double>() / 1e6, pc["99.000000"].get<double>() * 1e-6, pc["50.000000"].get<double>() * 1e-6};
}

}  // namespace

int main(int argc, char** argv) {
  vb::Harness h("io", argc, argv);
  const std::uint64_t size = h.pick<std::uint64_t>(8192, 2048);
  const int threads = 4;
  const std::size_t reads = h.pick<std::size_t>(4000, 800);
  TempDir dir;
  const std::string path = (dir.path / "raw.vts").string();
  write_raw_store(path, size);
  const TileStore store = TileStore::open(path);
  h.param("file", {{"texture", size}, {"bytes", store.header().file_bytes}, {"record_bytes", 49152}});
  h.param("threads", threads);
  h.param("reads_per_rep", reads);
  std::vector<TileKey> all;
  for (std::uint64_t s = 0; s < store.geometry().tile_count(); ++s) all.push_back(store.geometry().key_of_slot(s));

  // psync as the pool has always run (4 threads), then io_uring by depth (h.pick: fewer in quick mode).
  std::vector<Case> cases = {{IoEngine::psync, threads, 1}, {IoEngine::io_uring, 1, 1}, {IoEngine::io_uring, 1, 4},
                             {IoEngine::io_uring, 1, 16}, {IoEngine::io_uring, 1, 32}, {IoEngine::io_uring, threads, 16}};
  if (const char* only = std::getenv("VTSIM_BENCH_IO_CASES")) {  // e.g. "randread_48k,uring_t1_qd16"
    std::vector<Case> kept;
    for (const Case& c : cases)
      if ((std::string(",") + only + ",").find("," + c.name() + ",") != std::string::npos)
        kept.push_back(c);
    cases = kept;
  }
  struct Series {
    std::vector<double> ours_bw, fio_bw, ours_p99, fio_p99, ours_p50, fio_p50;
  };
  std::vector<Series> series(cases.size());
  try {
    for (int i = -h.options().warmup; i < h.options().reps; ++i) {
      std::mt19937_64 rng(static_cast<std::uint64_t>(i + 100));
      std::shuffle(all.begin(), all.end(), rng);
      std::vector<TileKey> keys;
      for (std::size_t k = 0; k < reads; ++k) keys.push_back(all[k % all.size()]);
      for (std::size_t ci = 0; ci < cases.size(); ++ci) {
        const Case& c = cases[ci];
        Rep a, b;
        if (i % 2 == 0) {
          a = run_pool(store, c, keys);
          b = run_fio(store, c, reads);
        } else {
          b = run_fio(store, c, reads);
          a = run_pool(store, c, keys);
        }
        if (i < 0) continue;  // warm-up
        Series& s = series[ci];
        s.ours_bw.push_back(a.MBps), s.fio_bw.push_back(b.MBps);
        s.ours_p99.push_back(a.p99_ms), s.fio_p99.push_back(b.p99_ms);
        s.ours_p50.push_back(a.p50_ms), s.fio_p50.push_back(b.p50_ms);
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_io: %s\n", e.what());
    return 3;
  }
  for (std::size_t ci = 0; ci < cases.size(); ++ci) {
    const Case& c = cases[ci];
    const Series& s = series[ci];
    const bool uring = c.engine == IoEngine::io_uring;
    const nlohmann::json params = {{"block_bytes", 49152}, {"threads", c.threads}, {"iodepth", c.depth}, {"reads", reads},
                                   {"engine", uring ? "io_uring, O_DIRECT, registered buffers and file" : "psync, O_DIRECT"}};
    // Targets: psync >= 0.9x fio psync; io_uring >= 0.9x fio io_uring at depth 16 (other depths reported).
    const double bw_target = !uring || c.depth == 16 ? 0.9 : 0.0, p99_target = !uring || c.depth == 16 ? 1.0 / 1.2 : 0.0;
    h.add_measured({.name = c.name() + "_bandwidth", .metric = vb::Metric::kMBPerS, .work = 1, .params = params, .target_ratio = bw_target},
                   "io_pool", s.ours_bw, "fio", s.fio_bw);
    h.add_measured({.name = c.name() + "_p99_ms", .metric = vb::Metric::kMsPerRep, .work = 1, .params = params,
                    .target_ratio = p99_target},
                   "io_pool", s.ours_p99, "fio", s.fio_p99);
    h.add_measured({.name = c.name() + "_p50_ms", .metric = vb::Metric::kMsPerRep, .work = 1, .params = params},
                   "io_pool", s.ours_p50, "fio", s.fio_p50);
  }
  return h.finish();
}
