// The decode stage (src/stream/exec/decode_pool.h) against calling the codec directly on the same tiles
// with the same number of threads, side by side in one run (issue 6: >= 0.9x per worker), for the
// store's two codecs (zstd albedo, lz4 normals), and its scaling with workers. The pool's side
// includes everything the stage does per tile (checksum, queue, wake-up, decoded-buffer hand-out,
// result hand-off); the reference does the same tile work directly (XXH64 of the record, then the
// codec), and the checksum's own cost is reported on its own.
// docs/real-engine.md carries the figures.
#include <malloc.h>
#include <stdlib.h>

#include <atomic>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <thread>

#include "harness.h"
#include "stream/exec/decode_pool.h"
#include "stream/store/i_codec.h"
#include "stream/store/store_generator.h"

namespace {

using namespace vtsim;
namespace vb = vtsim::bench;

struct Record {
  TileKey key;
  std::vector<std::uint8_t> bytes;  // payload padded to the aligned read, as the IO pool delivers it
  std::uint32_t stored = 0, decoded = 0;
  store::CodecId codec = store::CodecId::raw;
};

struct TempDir {
  std::filesystem::path path;
  TempDir() {
    std::string t = (std::filesystem::temp_directory_path() / "vtsim-bench-decode-XXXXXX").string();
    if (!mkdtemp(t.data())) throw std::runtime_error("mkdtemp failed");
    path = t;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};

// W threads, each decoding a contiguous share of `recs` with `fn`.
template <class Fn>
void run_threads(int w, const std::vector<Record>& recs, Fn fn) {
  std::vector<std::thread> t;
  for (int i = 0; i < w; ++i)
    t.emplace_back([&, i] {
      const std::size_t a = recs.size() * static_cast<std::size_t>(i) / static_cast<std::size_t>(w);
      const std::size_t b = recs.size() * static_cast<std::size_t>(i + 1) / static_cast<std::size_t>(w);
      std::vector<std::uint8_t> out(recs.empty() ? 0 : recs[0].decoded);
      for (std::size_t k = a; k < b; ++k) fn(recs[k], out.data());
    });
  for (auto& x : t) x.join();
}

// A record buffer pool for `recs`, and one decode task per record copied into its buffers (what the
// IO pool hands the decode stage); untimed set-up of the pool cases.
std::shared_ptr<BufferPool> record_buffers(const std::vector<Record>& recs) {
  std::size_t largest = 0;
  for (const Record& rec : recs) largest = std::max(largest, rec.bytes.size());
  return std::make_shared<BufferPool>(largest, recs.size() + 8);
}
void fill_tasks(BufferPool& buffers, const std::vector<Record>& recs, std::vector<DecodeTask>& tasks) {
  tasks.clear();
  for (std::size_t i = 0; i < recs.size(); ++i) {
    RecordBuffer b = buffers.acquire();
    std::copy(recs[i].bytes.begin(), recs[i].bytes.end(), b.data());
    tasks.push_back(DecodeTask{i + 1, recs[i].key, 0, std::move(b), recs[i].bytes.size()});
  }
}

}  // namespace

int main(int argc, char** argv) {
  vb::Harness h("decode", argc, argv);
  const std::uint64_t size = h.pick<std::uint64_t>(2048, 1024);
  TempDir dir;
  const std::string path = (dir.path / "decode.vts").string();
  GenOptions g;
  g.width = g.height = size;
  g.tile = 128;
  g.border = 4;
  g.seed = 1;
  g.layers = parse_gen_layers("albedo:zstd,normal:lz4", "layers");
  generate_store(g, path);
  const TileStore store = TileStore::open(path);
  const int copies = h.pick(8, 1);
  h.param("store", {{"size", size}, {"tile", 128}, {"border", 4}, {"layers", "albedo:zstd,normal:lz4"}});
  h.param("passes_per_rep", copies);

  ReadFile f = open_for_read(path, false).file;
  struct Later {
    std::vector<Record> recs;
    std::string codec;
    double decoded_bytes;
  };
  std::vector<Later> later;  // the kept-results cases, run last
  for (std::uint32_t layer = 0; layer < 2; ++layer) {
    std::vector<Record> recs;
    double decoded_bytes = 0;
    for (std::int64_t y = 0; y < static_cast<std::int64_t>(store.geometry().rows[0]); ++y)
      for (std::int64_t x = 0; x < static_cast<std::int64_t>(store.geometry().cols[0]); ++x) {
        const TileKey k(layer, 0, x, y);
        const TileLocation loc = store.locate(k);
        Record r;
        r.key = k;
        r.stored = loc.stored_bytes;
        r.decoded = loc.decoded_bytes;
        r.codec = store.index()[store.geometry().slot(k)].codec;
        r.bytes.resize(loc.read_bytes);
        f.pread_full(r.bytes.data(), loc.read_bytes, loc.offset);
        decoded_bytes += loc.decoded_bytes;
        recs.push_back(std::move(r));
      }
    // Level 0 of a 2048² store is 256 tiles, ~5 ms of lz4 on one core: too short a repetition on a
    // shared machine, where one descheduling moves it by 20%. Each repetition decodes the level
    // `copies` times over (separate records, as distinct reads would be).
    const std::size_t one_pass = recs.size();
    for (int c = 1; c < copies; ++c)
      for (std::size_t i = 0; i < one_pass; ++i) recs.push_back(recs[i]);
    decoded_bytes *= copies;
    const std::string codec(codec_name(store.layer(layer).codec));
    // Both sides must produce the same texels: check once before timing.
    {
      std::vector<std::uint8_t> out(recs[0].decoded);
      decoder_for(recs[0].codec).decode(recs[0].bytes.data(), recs[0].stored, 136, 136, 3, out.data());
      const DecodeResult r = decode_record(store, recs[0].key, recs[0].bytes.data(), recs[0].bytes.size(), true);
      if (r.fault != Fault::none || !std::equal(out.begin(), out.end(), r.data->texels.get())) {
        std::fprintf(stderr, "bench_decode: the pool's decode differs from the codec's\n");
        return 3;
      }
    }
    h.run({.name = codec + "_checksum",
           .metric = vb::Metric::kMBPerS,
           .work = decoded_bytes,
           .params = {{"codec", codec}, {"tiles", recs.size()}, {"what", "XXH64 of the stored payloads (decode stage, before the codec), per decoded MB"}}},
          {"xxh64", {}, [&] {
             std::uint64_t x = 0;
             for (const Record& rec : recs) x ^= store::checksum64(rec.bytes.data(), rec.stored);
             vb::do_not_optimize(x);
           }});
    double one_worker = 0;
    for (int w : {1, 2, 4}) {
      auto buffers = record_buffers(recs);
      std::vector<DecodeTask> tasks;
      auto setup = [&] { fill_tasks(*buffers, recs, tasks); };
      std::atomic<std::size_t> failures{0};
      auto pool_run = [&] {
        std::mutex m;
        std::condition_variable cv;
        std::size_t done = 0;
        WallClock clock;
        DecodePool pool(store, w, clock, [&](DecodeResult&& r) {
          if (r.fault != Fault::none) failures.fetch_add(1);
          vb::do_not_optimize(r.data);
          std::lock_guard lock(m);
          if (++done == recs.size()) cv.notify_one();
        });
        for (auto& t : tasks) pool.submit(t);
        std::unique_lock lock(m);
        cv.wait(lock, [&] { return done == recs.size(); });
      };
      const vb::Case c{.name = codec + "_w" + std::to_string(w),
                       .metric = vb::Metric::kMBPerS,
                       .work = decoded_bytes,
                       .params = {{"codec", codec}, {"workers", w}, {"tiles", recs.size()}, {"reference", "codec"}},
                       .target_ratio = 0.9};
      const vb::Result* r = h.compare(c, {"decode_pool", setup, pool_run}, {"codec_direct", {}, [&] {
                                        run_threads(w, recs, [&](const Record& rec, std::uint8_t* out) {
                                          vb::do_not_optimize(store::checksum64(rec.bytes.data(), rec.stored));
                                          decoder_for(rec.codec).decode(rec.bytes.data(), rec.stored, 136, 136, 3, out);
                                          vb::do_not_optimize(out[0]);
                                        });
                                      }});
      if (failures.load()) {
        std::fprintf(stderr, "bench_decode: %zu decodes failed\n", failures.load());
        return 3;
      }
      if (r && w == 1) one_worker = r->ours.median;
      if (r && one_worker > 0)
        std::printf("  %s: %d workers decode %.2fx one worker (%u cores)\n", codec.c_str(), w, r->ours.median / one_worker,
                    std::thread::hardware_concurrency());
    }

    later.push_back({std::move(recs), codec, decoded_bytes});
  }
  // After every other case: the mallopt below changes how the process allocates from then on.
  for (auto& [recs, codec, decoded_bytes] : later) {
    // The real clock's RAM cache keeps every decoded tile, so without a reserve each decode writes
    // memory nothing has touched yet. Both sides keep their results (2 workers); the reference's
    // buffers are new mappings each repetition (mallopt below: freed memory is unmapped, not reused),
    // ours come from TileBufferPool::reserve, mapped and written in the untimed setup.
    auto buffers = record_buffers(recs);
    std::vector<DecodeTask> tasks;
    std::vector<std::shared_ptr<const TileData>> kept;
    std::unique_ptr<DecodePool> pool;
    std::mutex m;
    std::condition_variable cv;
    std::size_t done = 0;
    std::atomic<std::size_t> failures{0};
    WallClock clock;
    const auto setup = [&](bool reserve) {
      pool.reset();
      kept.clear();
      kept.reserve(recs.size());
      done = 0;
      fill_tasks(*buffers, recs, tasks);
      pool = std::make_unique<DecodePool>(store, 2, clock, [&](DecodeResult&& r) {
        if (r.fault != Fault::none) failures.fetch_add(1);
        std::lock_guard lock(m);
        kept.push_back(std::move(r.data));
        if (++done == recs.size()) cv.notify_one();
      });
      if (reserve) pool->reserve_tiles(recs[0].decoded, recs.size());
    };
    const auto run = [&] {
      for (auto& t : tasks) pool->submit(t);
      std::unique_lock lock(m);
      cv.wait(lock, [&] { return done == recs.size(); });
    };
    mallopt(M_MMAP_THRESHOLD, 16 * 1024);  // fixed (no dynamic raise): every tile buffer its own mapping
    mallopt(M_TRIM_THRESHOLD, 0);
    h.compare({.name = codec + "_kept_w2",
               .metric = vb::Metric::kMBPerS,
               .work = decoded_bytes,
               .params = {{"codec", codec}, {"workers", 2}, {"tiles", recs.size()}, {"reference", "fresh buffers"},
                          {"what", "decoded tiles kept, as the RAM cache keeps them: reserved buffers vs memory never touched"}}},
              {"reserved", [&] { setup(true); }, run}, {"fresh_buffers", [&] { setup(false); }, run});
    pool.reset();
    kept.clear();
    if (failures.load()) {
      std::fprintf(stderr, "bench_decode: %zu decodes failed\n", failures.load());
      return 3;
    }
  }
  return h.finish();
}
