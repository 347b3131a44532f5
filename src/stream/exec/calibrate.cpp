#include "stream/exec/calibrate.h"

#include <fmt/format.h>
#include <liburing.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <latch>
#include <limits>
#include <numeric>
#include <random>
#include <system_error>
#include <thread>

#include "core/error.h"
#include "stream/store/aligned_io.h"
#include "stream/exec/decode_pool.h"
#include "stream/exec/io_pool.h"
#include "stream/store/i_codec.h"

namespace vtsim {

namespace {

using Clock = std::chrono::steady_clock;

double pct(std::vector<double>& v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(std::ceil(p * static_cast<double>(v.size()))) ;
  return v[std::min(v.size() - 1, i == 0 ? 0 : i - 1)];  // nearest rank, as docs/metrics.md
}

// `conc` threads, each with one read of `bytes` in flight at a time, at uniform random aligned
// offsets in [lo, hi), for `seconds`. Aggregate bandwidth is bytes / (first start .. last end).
// One calibration point from each reader's latencies (µs) over the elapsed seconds: the same
// figures for the psync threads and the io_uring rings.
ReadPoint read_point(const std::vector<std::vector<double>>& lat, std::uint32_t bytes, int concurrency, int depth,
                     double elapsed) {
  ReadPoint p;
  p.bytes = bytes;
  p.concurrency = concurrency;
  p.depth = depth;
  std::vector<double> all;
  for (const auto& v : lat) all.insert(all.end(), v.begin(), v.end());
  p.reads = all.size();
  p.MBps = elapsed > 0 ? static_cast<double>(p.reads) * bytes / elapsed / 1e6 : 0;
  p.mean_us = all.empty() ? 0 : std::accumulate(all.begin(), all.end(), 0.0) / static_cast<double>(all.size());
  p.p50_us = pct(all, 0.50);
  p.p95_us = pct(all, 0.95);
  p.p99_us = pct(all, 0.99);
  return p;
}

ReadPoint measure_reads(const ReadFile& f, std::uint64_t lo, std::uint64_t hi, std::uint32_t bytes, int conc, double seconds,
                        std::uint64_t seed) {
  const std::uint64_t slots = (hi - lo - bytes) / store::kAlign + 1;
  std::vector<std::vector<double>> lat(static_cast<std::size_t>(conc));
  std::vector<std::string> errors(static_cast<std::size_t>(conc));
  std::latch start(conc + 1);
  std::vector<std::thread> threads;
  Clock::time_point t_begin, t_end;
  std::atomic<std::int64_t> last_end_ns{0};
  for (int i = 0; i < conc; ++i)
    threads.emplace_back([&, i] {
      AlignedBuffer buf(bytes);
      std::mt19937_64 rng(seed * 1000003u + static_cast<std::uint64_t>(i));
      auto& mine = lat[static_cast<std::size_t>(i)];
      start.arrive_and_wait();
      const auto deadline = Clock::now() + std::chrono::duration<double>(seconds);
      try {
        for (;;) {
          const std::uint64_t off = lo + (rng() % slots) * store::kAlign;
          const auto a = Clock::now();
          if (a >= deadline) break;
          if (f.pread_full(buf.data(), bytes, off) != bytes) throw std::runtime_error("short read");
          const auto b = Clock::now();
          mine.push_back(std::chrono::duration<double, std::micro>(b - a).count());
          std::int64_t ns = std::chrono::duration_cast<std::chrono::nanoseconds>(b.time_since_epoch()).count();
          std::int64_t prev = last_end_ns.load();
          while (ns > prev && !last_end_ns.compare_exchange_weak(prev, ns)) {
          }
        }
      } catch (const std::exception& e) {
        errors[static_cast<std::size_t>(i)] = e.what();
      }
    });
  start.arrive_and_wait();
  t_begin = Clock::now();
  for (auto& t : threads) t.join();
  for (const auto& e : errors)
    if (!e.empty()) throw InputError(f.path(), "calibration read failed: " + e);
  t_end = Clock::time_point(std::chrono::duration_cast<Clock::duration>(std::chrono::nanoseconds(last_end_ns.load())));
  return read_point(lat, bytes, conc, 1, std::chrono::duration<double>(t_end - t_begin).count());
}

// io_uring: `threads` threads, each with its own ring keeping `depth` reads of `bytes` in flight
// (registered buffers and file, as the IO pool's io_uring engine) at uniform random aligned offsets
// in [lo, hi), for `seconds`. A read's latency is submission to completion.
ReadPoint measure_ring_reads(const ReadFile& f, std::uint64_t lo, std::uint64_t hi, std::uint32_t bytes, int threads, int depth,
                             double seconds, std::uint64_t seed) {
  const std::uint64_t slots = (hi - lo - bytes) / store::kAlign + 1;
  std::vector<std::vector<double>> lat(static_cast<std::size_t>(threads));
  std::vector<std::string> errors(static_cast<std::size_t>(threads));
  std::latch start(threads + 1);
  std::vector<std::thread> pool;
  std::atomic<std::int64_t> last_end_ns{0};
  for (int i = 0; i < threads; ++i)
    pool.emplace_back([&, i] {
      auto& mine = lat[static_cast<std::size_t>(i)];
      io_uring ring{};
      const int rc = io_uring_queue_init(static_cast<unsigned>(depth), &ring, 0);
      AlignedBuffer buf(static_cast<std::size_t>(bytes) * static_cast<std::size_t>(depth));
      int fixed_buf = 0, fixed_file = 0;
      if (rc == 0) {
        const iovec iov{buf.data(), buf.size()};
        fixed_buf = io_uring_register_buffers(&ring, &iov, 1) == 0;
        const int fd = f.fd();
        fixed_file = io_uring_register_files(&ring, &fd, 1) == 0;
      }
      std::mt19937_64 rng(seed * 1000003u + static_cast<std::uint64_t>(i));
      std::vector<Clock::time_point> issued(static_cast<std::size_t>(depth));
      start.arrive_and_wait();
      if (rc < 0) {
        errors[static_cast<std::size_t>(i)] = std::string("io_uring_queue_init: ") + std::strerror(-rc);
        return;
      }
      const auto deadline = Clock::now() + std::chrono::duration<double>(seconds);
      auto issue = [&](int k) {
        io_uring_sqe* e = io_uring_get_sqe(&ring);
        std::uint8_t* dst = buf.data() + static_cast<std::size_t>(k) * bytes;
        const std::uint64_t off = lo + (rng() % slots) * store::kAlign;
        const int fd = fixed_file ? 0 : f.fd();
        if (fixed_buf) io_uring_prep_read_fixed(e, fd, dst, bytes, off, 0);
        else io_uring_prep_read(e, fd, dst, bytes, off);
        if (fixed_file) io_uring_sqe_set_flags(e, IOSQE_FIXED_FILE);
        io_uring_sqe_set_data64(e, static_cast<std::uint64_t>(k));
        issued[static_cast<std::size_t>(k)] = Clock::now();
      };
      int in_flight = 0;
      for (int k = 0; k < depth; ++k, ++in_flight) issue(k);
      io_uring_submit(&ring);
      while (in_flight > 0) {
        io_uring_cqe* cqe = nullptr;
        const int w = io_uring_wait_cqe(&ring, &cqe);
        if (w == -EINTR) continue;
        if (w < 0) {
          errors[static_cast<std::size_t>(i)] = std::string("io_uring_wait_cqe: ") + std::strerror(-w);
          break;
        }
        const auto b = Clock::now();
        const int k = static_cast<int>(cqe->user_data);
        const int res = cqe->res;
        io_uring_cqe_seen(&ring, cqe);
        --in_flight;
        if (res != static_cast<int>(bytes)) {
          if (errors[static_cast<std::size_t>(i)].empty())
            errors[static_cast<std::size_t>(i)] = res < 0 ? std::string(std::strerror(-res)) : "short read";
          continue;
        }
        mine.push_back(std::chrono::duration<double, std::micro>(b - issued[static_cast<std::size_t>(k)]).count());
        std::int64_t ns = std::chrono::duration_cast<std::chrono::nanoseconds>(b.time_since_epoch()).count();
        std::int64_t prev = last_end_ns.load();
        while (ns > prev && !last_end_ns.compare_exchange_weak(prev, ns)) {
        }
        if (b < deadline && errors[static_cast<std::size_t>(i)].empty()) {
          issue(k);
          ++in_flight;
          io_uring_submit(&ring);
        }
      }
      io_uring_queue_exit(&ring);
    });
  start.arrive_and_wait();
  const Clock::time_point t_begin = Clock::now();
  for (auto& t : pool) t.join();
  for (const auto& e : errors)
    if (!e.empty()) throw InputError(f.path(), "calibration read failed: " + e);
  const Clock::time_point t_end(std::chrono::duration_cast<Clock::duration>(std::chrono::nanoseconds(last_end_ns.load())));
  return read_point(lat, bytes, threads * depth, depth, std::chrono::duration<double>(t_end - t_begin).count());
}

struct Sample {
  TileKey key;
  std::vector<std::uint8_t> record;  // the stored payload, padded to the aligned read
  std::uint32_t stored = 0, decoded = 0;
};

// Least squares y = a + b x.
void fit_line(const std::vector<double>& x, const std::vector<double>& y, double& a, double& b) {
  const double n = static_cast<double>(x.size());
  const double mx = std::accumulate(x.begin(), x.end(), 0.0) / n, my = std::accumulate(y.begin(), y.end(), 0.0) / n;
  double sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sxx += (x[i] - mx) * (x[i] - mx);
    sxy += (x[i] - mx) * (y[i] - my);
  }
  b = sxx > 0 ? sxy / sxx : 0;
  a = my - b * mx;
}

}  // namespace

DiskModel fit_disk_model(const std::vector<ReadPoint>& points, int io_threads, std::uint32_t typical_bytes,
                         std::vector<std::string>* notes) {
  struct P {
    double s, c, X, w;
  };
  std::vector<P> use;
  for (const auto& p : points)
    if (p.concurrency <= io_threads && p.MBps > 0)
      use.push_back({static_cast<double>(p.bytes), static_cast<double>(p.concurrency), p.MBps * 1e6,
                     p.bytes == typical_bytes ? 4.0 : 1.0});
  if (use.empty()) throw std::invalid_argument("fit_disk_model: no read points at or below io_threads");
  const auto err = [&](double L_us, double B) {
    double e = 0;
    for (const P& p : use) {
      const double r = std::log(disk_throughput_Bps(DiskModel{L_us, B / 1e6, static_cast<int>(p.c)}, p.s) / p.X);
      e += p.w * r * r;
    }
    return e;
  };
  // Grid search in log space (latency 0.1 us .. 1 s, bandwidth 1 MB/s .. 1 TB/s), then two finer
  // grids around the best cell: the objective is smooth but not convex near the bus knee.
  double bestL = 0, bestB = 0, best = std::numeric_limits<double>::infinity();
  double l0 = std::log(0.1), l1 = std::log(1e6), b0 = std::log(1e6), b1 = std::log(1e12);
  for (int pass = 0; pass < 3; ++pass) {
    const int n = 120;
    for (int i = 0; i <= n; ++i)
      for (int j = 0; j <= n; ++j) {
        const double L = std::exp(l0 + (l1 - l0) * i / n), B = std::exp(b0 + (b1 - b0) * j / n);
        const double e = err(L, B);
        if (e < best) best = e, bestL = L, bestB = B;
      }
    const double dl = 3 * (l1 - l0) / n, db = 3 * (b1 - b0) / n;
    l0 = std::log(bestL) - dl, l1 = std::log(bestL) + dl, b0 = std::log(bestB) - db, b1 = std::log(bestB) + db;
  }
  const DiskModel m{bestL, bestB / 1e6, io_threads};
  if (notes) {
    std::string r;
    for (const auto& p : points)
      if (p.concurrency <= io_threads)
        r += fmt::format(" {}K×{} {:+.0f}%", p.bytes / 1024, p.concurrency,
                         100.0 * (disk_throughput_Bps(DiskModel{m.latency_us, m.bandwidth_MBps, p.concurrency}, p.bytes) / 1e6 / p.MBps - 1));
    notes->push_back("disk fit (model vs measured MB/s, size×in flight):" + r);
  }
  return m;
}

namespace {

// The store's mean read (its records rounded up to whole 4 KiB blocks), bytes.
double store_mean_read_bytes(const TileStore& store) {
  std::uint64_t read_bytes = 0, tiles = 0;
  for (const auto& t : store.totals()) read_bytes += t.read_bytes, tiles += t.tiles;
  return static_cast<double>(read_bytes) / static_cast<double>(tiles);
}

// The request sizes to measure, bytes, ascending: `sizes` as asked (empty: 4, 16, 64, 256 KiB) and
// the store's typical read. Throws InputError("--sizes") for a size that is not a positive multiple of
// 4096 or exceeds the data region.
std::vector<std::uint32_t> calibration_sizes(std::vector<std::uint32_t> sizes, std::uint32_t typical,
                                             std::uint64_t data_bytes) {
  if (sizes.empty()) sizes = {4096, 16384, 65536, 262144};
  if (std::find(sizes.begin(), sizes.end(), typical) == sizes.end()) sizes.push_back(typical);
  std::sort(sizes.begin(), sizes.end());
  for (std::uint32_t s : sizes) {
    if (s == 0 || s % store::kAlign != 0) throw InputError("--sizes", fmt::format("{} is not a positive multiple of 4096", s));
    if (s > data_bytes) throw InputError("--sizes", fmt::format("{} bytes is larger than the store's data region ({} bytes)", s, data_bytes));
  }
  return sizes;
}

// The reads in flight to measure, ascending: `conc` as asked (empty: 1, 2, 4, 8) and io_threads.
// Throws InputError("--concurrency") outside 1..256.
std::vector<int> calibration_concurrency(std::vector<int> conc, int io_threads) {
  if (conc.empty()) conc = {1, 2, 4, 8};
  if (std::find(conc.begin(), conc.end(), io_threads) == conc.end()) conc.push_back(io_threads);
  std::sort(conc.begin(), conc.end());
  for (int k : conc)
    if (k < 1 || k > 256) throw InputError("--concurrency", fmt::format("{} is outside 1..256", k));
  return conc;
}

// `per_layer` random tiles of each layer (fewer when the layer has fewer), read through the page
// cache: the records the decode measurements replay.
std::vector<std::vector<Sample>> sample_decode_tiles(const TileStore& store, std::uint32_t per_layer, std::uint64_t seed) {
  ReadFile f = open_for_read(store.path(), false).file;
  std::mt19937_64 rng(seed);
  std::vector<std::vector<Sample>> by_layer(store.layer_count());
  const std::uint64_t slots = store.geometry().tiles_per_layer;
  for (std::uint32_t L = 0; L < store.layer_count(); ++L)
    for (std::uint32_t i = 0; i < std::min<std::uint64_t>(per_layer, slots); ++i) {
      const TileKey k = store.geometry().key_of_slot(L * slots + rng() % slots);
      const TileLocation loc = store.locate(k);
      Sample s;
      s.key = k;
      s.stored = loc.stored_bytes;
      s.decoded = loc.decoded_bytes;
      s.record.resize(loc.read_bytes);
      if (f.pread_full(s.record.data(), loc.read_bytes, loc.offset) < loc.stored_bytes)
        throw InputError(store.path() + ": " + store::describe(k), "short read while sampling tiles");
      by_layer[L].push_back(std::move(s));
    }
  return by_layer;
}

// One worker on one layer (= one codec): the decode pool's work (checksum, then decode) on this
// thread, over the samples again and again for `seconds` and at least once each.
DecodePoint measure_layer_decode(const TileStore& store, std::uint32_t L, const std::vector<Sample>& samples, double seconds,
                                 const std::shared_ptr<TileBufferPool>& tile_buffers) {
  std::uint64_t n = 0;
  const auto t0 = Clock::now();
  const auto deadline = t0 + std::chrono::duration<double>(seconds);
  double stored = 0, decoded = 0;
  while (Clock::now() < deadline || n < samples.size())
    for (const Sample& s : samples) {
      const DecodeResult r = decode_record(store, s.key, s.record.data(), s.record.size(), /*verify=*/true, tile_buffers);
      if (r.fault != Fault::none) throw InputError(r.error, "calibration decode failed");
      stored += s.stored;
      decoded += s.decoded;
      ++n;
    }
  const double secs = std::chrono::duration<double>(Clock::now() - t0).count();
  DecodePoint p;
  p.what = fmt::format("layer {} ({})", store.layer(L).name, codec_name(store.layer(L).codec));
  p.workers = 1;
  p.tiles = n;
  p.us_per_tile = secs * 1e6 / static_cast<double>(n);
  p.tiles_per_s = static_cast<double>(n) / secs;
  p.decoded_MBps = decoded / secs / 1e6;
  p.stored_bytes = stored / static_cast<double>(n);
  p.decoded_bytes = decoded / static_cast<double>(n);
  return p;
}

// The pool's worker counts to measure, ascending: powers of two up to max(decode_workers, 2), and
// decode_workers.
std::vector<int> pool_worker_counts(int decode_workers) {
  std::vector<int> workers_list;
  for (int w = 1; w <= std::max(decode_workers, 2); w *= 2) workers_list.push_back(w);
  if (std::find(workers_list.begin(), workers_list.end(), decode_workers) == workers_list.end()) workers_list.push_back(decode_workers);
  std::sort(workers_list.begin(), workers_list.end());
  return workers_list;
}

// The decode pool with `w` workers for `seconds`, fed the layers' samples in turn (every layer of a
// tile, as a replay requests them); `buffers` holds records of the largest sample.
DecodePoint measure_decode_pool(const TileStore& store, const std::vector<std::vector<Sample>>& by_layer, int w, double seconds,
                                const std::shared_ptr<BufferPool>& buffers) {
  WallClock clock;
  std::atomic<std::uint64_t> done{0}, failed{0};
  std::uint64_t submitted = 0;
  double decoded = 0;
  const auto t0 = Clock::now();
  {
    DecodePool pool(store, w, clock, [&](DecodeResult&& r) {
      if (r.fault != Fault::none) failed.fetch_add(1);
      done.fetch_add(1, std::memory_order_release);
    });
    const auto deadline = t0 + std::chrono::duration<double>(seconds);
    // Keep 32 tasks per worker queued: this thread refills after sleeping >= 50 us, and with only a
    // few tasks (~25 us each) per worker the workers ran dry between refills, which measured the
    // refill loop rather than the pool (2 workers "reached 1.05x one worker" on 2 idle cores).
    std::size_t i = 0;
    std::vector<const Sample*> order;
    for (std::size_t j = 0; j < by_layer[0].size(); ++j)
      for (const auto& v : by_layer)
        if (j < v.size()) order.push_back(&v[j]);
    while (Clock::now() < deadline) {
      while (submitted - done.load(std::memory_order_acquire) < static_cast<std::uint64_t>(32 * w)) {
        const Sample& s = *order[i++ % order.size()];
        RecordBuffer b = buffers->acquire();
        std::copy(s.record.begin(), s.record.end(), b.data());
        DecodeTask t{submitted + 1, s.key, 0, std::move(b), s.record.size()};
        pool.submit(t);
        ++submitted;
        decoded += s.decoded;
      }
      std::this_thread::sleep_for(std::chrono::microseconds(50));
    }
    while (done.load(std::memory_order_acquire) < submitted) std::this_thread::sleep_for(std::chrono::microseconds(50));
  }
  const double secs = std::chrono::duration<double>(Clock::now() - t0).count();
  if (failed.load()) throw InputError(store.path(), "calibration decode failed in the pool");
  DecodePoint p;
  p.what = "pool (layer mix)";
  p.workers = w;
  p.tiles = submitted;
  p.tiles_per_s = static_cast<double>(submitted) / secs;
  p.us_per_tile = secs * 1e6 * w / static_cast<double>(submitted);
  p.decoded_MBps = decoded / secs / 1e6;
  p.decoded_bytes = decoded / static_cast<double>(submitted);
  return p;
}

// The decode model from the per-layer means on one worker (layer_us: us per tile; layer_decoded:
// decoded bytes per tile) and the pool's measured tiles/s at `workers` (0: not measured). Cost per
// tile on one worker: per_tile + bytes / throughput by least squares over layers when their decoded
// sizes differ, else a per-tile cost only. Then scaled by the pool's measured speed-up at `workers`
// (workers share cores with IO and the frame loop). How it went goes to `notes`.
DecodeModel fit_decode_model(const std::vector<double>& layer_us, const std::vector<double>& layer_decoded, int workers,
                             double pool_tiles_per_s, std::vector<std::string>& notes) {
  double per_tile = 0, per_byte = 0;
  const bool sizes_differ = std::adjacent_find(layer_decoded.begin(), layer_decoded.end(), std::not_equal_to<>()) != layer_decoded.end();
  if (sizes_differ) fit_line(layer_decoded, layer_us, per_tile, per_byte);
  if (!sizes_differ || per_tile < 0 || per_byte <= 0) {
    per_tile = std::accumulate(layer_us.begin(), layer_us.end(), 0.0) / static_cast<double>(layer_us.size());
    per_byte = 0;
  }
  const double solo_tiles_per_s = 1e6 / (per_tile + per_byte * std::accumulate(layer_decoded.begin(), layer_decoded.end(), 0.0) /
                                                       static_cast<double>(layer_decoded.size()));
  const double scale = pool_tiles_per_s > 0 ? workers * solo_tiles_per_s / pool_tiles_per_s : 1.0;
  DecodeModel m;
  m.per_tile_us = per_tile * scale;
  m.throughput_MBps = per_byte > 0 ? 1.0 / (per_byte * scale) : 0.0;
  m.workers = workers;
  notes.push_back(fmt::format("decode: {:.1f} us per tile on one worker; {} workers reach {:.2f}x one worker, so each counts "
                              "{:.1f} us per tile",
                              1e6 / solo_tiles_per_s, workers, pool_tiles_per_s / solo_tiles_per_s, m.per_tile_us));
  return m;
}

}  // namespace

Calibration calibrate(const TileStore& store, const CalibrateOptions& o, const CalibrateProgress& progress) {
  if (o.io_threads < 1 || o.io_threads > 256) throw InputError("--io-threads", "must be in 1..256");
  if (o.decode_workers < 1 || o.decode_workers > 256) throw InputError("--decode-workers", "must be in 1..256");
  if (!(o.seconds_per_point > 0 && o.seconds_per_point <= 60)) throw InputError("--seconds", "must be in (0, 60]");
  Calibration c;
  c.io_threads = o.io_threads;
  const auto say = [&](const std::string& s) {
    if (progress) progress(s);
  };

  // ---- disk ----
  DirectOpen d = open_for_read(store.path(), o.direct);
  c.direct = d.file.direct();
  c.direct_warning = d.warning;
  const std::uint64_t lo = store.header().data_offset, hi = store.header().file_bytes;
  c.mean_read_bytes = store_mean_read_bytes(store);
  const auto typical = static_cast<std::uint32_t>(std::max<std::uint64_t>(store::kAlign, store::round_up(static_cast<std::uint64_t>(c.mean_read_bytes), store::kAlign)));
  const std::vector<std::uint32_t> sizes = calibration_sizes(o.sizes, typical, hi - lo);
  c.engine = o.engine;
  if (o.engine == IoEngine::io_uring) {
    checked_queue_depth(o.queue_depth);
    c.engine_warning = io_uring_unavailable(o.fail_ring_errno);
    if (!c.engine_warning.empty()) c.engine = IoEngine::psync;
  }
  if (c.engine == IoEngine::io_uring) {
    c.queue_depth = o.queue_depth;
    std::vector<int> depths = o.depths.empty() ? std::vector<int>{1, 4, 16, 32} : o.depths;
    if (std::find(depths.begin(), depths.end(), o.queue_depth) == depths.end()) depths.push_back(o.queue_depth);
    std::sort(depths.begin(), depths.end());
    for (int k : depths)
      if (k < 1 || k > 1024) throw InputError("--depths", fmt::format("{} is outside 1..1024", k));
    for (std::uint32_t s : sizes)
      for (int k : depths) {
        say(fmt::format("reads of {} KiB, {} threads x depth {}", s / 1024, o.io_threads, k));
        c.reads.push_back(measure_ring_reads(d.file, lo, hi, s, o.io_threads, k, o.seconds_per_point,
                                             o.seed + s + static_cast<std::uint64_t>(k)));
      }
  } else {
    const std::vector<int> conc = calibration_concurrency(o.concurrency, o.io_threads);
    for (std::uint32_t s : sizes)
      for (int k : conc) {
        say(fmt::format("reads of {} KiB, {} in flight", s / 1024, k));
        c.reads.push_back(measure_reads(d.file, lo, hi, s, k, o.seconds_per_point, o.seed + s + static_cast<std::uint64_t>(k)));
      }
  }

  // ---- decode ----
  const std::vector<std::vector<Sample>> by_layer = sample_decode_tiles(store, o.decode_sample, o.seed);
  auto tile_buffers = std::make_shared<TileBufferPool>();
  std::vector<double> layer_us, layer_decoded;
  for (std::uint32_t L = 0; L < store.layer_count(); ++L) {
    say(fmt::format("decode layer {} ({}), one worker", store.layer(L).name, codec_name(store.layer(L).codec)));
    c.decodes.push_back(measure_layer_decode(store, L, by_layer[L], o.seconds_per_point, tile_buffers));
    layer_us.push_back(c.decodes.back().us_per_tile);
    layer_decoded.push_back(c.decodes.back().decoded_bytes);
  }
  std::size_t max_record = 0;
  for (const auto& v : by_layer)
    for (const auto& s : v) max_record = std::max(max_record, s.record.size());
  auto buffers = std::make_shared<BufferPool>(max_record, 4096);
  double pool_tiles_per_s_at_w = 0;
  for (int w : pool_worker_counts(o.decode_workers)) {
    say(fmt::format("decode pool, {} workers", w));
    c.decodes.push_back(measure_decode_pool(store, by_layer, w, o.seconds_per_point, buffers));
    if (w == o.decode_workers) pool_tiles_per_s_at_w = c.decodes.back().tiles_per_s;
  }

  // ---- fit ----
  // The fit sees reads in flight (threads x depth); the model splits them back into channels (the
  // IO threads) and the ring's depth.
  c.disk = fit_disk_model(c.reads, o.io_threads * c.queue_depth, typical, &c.notes);
  c.disk.channels = o.io_threads;
  c.disk.queue_depth = c.queue_depth;
  c.decode = fit_decode_model(layer_us, layer_decoded, o.decode_workers, pool_tiles_per_s_at_w, c.notes);
  return c;
}

std::string profile_toml(const Calibration& c, const std::string& store_path) {
  char host[256] = {};
  gethostname(host, sizeof host - 1);
  const std::time_t now = std::time(nullptr);
  char when[32];
  std::strftime(when, sizeof when, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
  std::string t;
  t += fmt::format("# vtsim device profile: `vtsim calibrate --store {}` on {} at {}\n", store_path, host, when);
  t += "# Use with --config (or merge with --set) so the simulated clock predicts the real one (docs/real-engine.md).\n#\n";
  t += fmt::format("# reads ({}, {}, random offsets in the store file): size KiB, in flight, MB/s, latency mean/p50/p95/p99 us\n",
                   c.direct ? "O_DIRECT" : "page cache", c.engine == IoEngine::io_uring ? "io_uring" : "psync");
  if (!c.engine_warning.empty()) t += "# " + c.engine_warning + "\n";
  for (const auto& p : c.reads)
    t += fmt::format("#   {:>6} {:>3} {:>9.1f} {:>9.1f} {:>9.1f} {:>9.1f} {:>9.1f}\n", p.bytes / 1024, p.concurrency, p.MBps, p.mean_us,
                     p.p50_us, p.p95_us, p.p99_us);
  t += "# decode (the store's tiles, checksum + codec): what, workers, us per tile per worker, tiles/s, decoded MB/s\n";
  for (const auto& p : c.decodes)
    t += fmt::format("#   {:<28} {:>2} {:>9.1f} {:>10.0f} {:>9.1f}\n", p.what, p.workers, p.us_per_tile, p.tiles_per_s, p.decoded_MBps);
  for (const auto& n : c.notes) t += "# " + n + "\n";
  t += "\n[disk]\n";
  t += fmt::format("latency_us = {:.2f}        # per-request latency, fitted\n", c.disk.latency_us);
  t += fmt::format("bandwidth_MBps = {:.2f}    # shared transfer bandwidth, fitted\n", c.disk.bandwidth_MBps);
  t += fmt::format("channels = {}              # = io.threads: the IO pool's submitters\n", c.disk.channels);
  t += fmt::format("queue_depth = {}           # = io.queue_depth with io_uring, 1 with psync: reads in flight per thread\n",
                   c.disk.queue_depth);
  t += "\n[decode]\n";
  t += fmt::format("throughput_MBps = {:.2f}\n", c.decode.throughput_MBps);
  t += fmt::format("per_tile_us = {:.2f}\n", c.decode.per_tile_us);
  t += fmt::format("workers = {}\n", c.decode.workers);
  t += "\n[io]\n";
  t += fmt::format("threads = {}\n", c.io_threads);
  t += fmt::format("direct = {}\n", c.direct ? "true" : "false");
  t += fmt::format("engine = \"{}\"\n", engine_name(c.engine));
  if (c.engine == IoEngine::io_uring) t += fmt::format("queue_depth = {}\n", c.queue_depth);
  return t;
}

}  // namespace vtsim
