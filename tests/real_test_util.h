#pragma once
// Helpers for the real-engine tests: small generated stores (made once per test process), a
// scratch directory, copying and patching store files, running the CLI, waiting with a deadline.
#include <doctest/doctest.h>
#include <stdlib.h>
#include <sys/wait.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "stream/exec/i_executor.h"
#include "stream/exec/io_pool.h"
#include "stream/store/tile_store.h"
#include "test_util.h"

namespace vtsim::test {

class RealScratch {
 public:
  RealScratch() {
    std::string t = (std::filesystem::temp_directory_path() / "vtsim-real-test-XXXXXX").string();
    if (!mkdtemp(t.data())) throw std::runtime_error("mkdtemp failed");
    path_ = t;
  }
  ~RealScratch() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  RealScratch(const RealScratch&) = delete;
  RealScratch& operator=(const RealScratch&) = delete;
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

// 1024² texels, tile 64, no border, every level, albedo (zstd) + normal (lz4): 2 × 341 tiles,
// made once per build tree (real_test_util.cpp). Tests that change a store copy it first.
const std::string& small_store();
// The same texture as virtual-texture pages: 1024² texels, page 64 with a 4-texel border (72²
// stored), every level, albedo (zstd) + normal (lz4).
const std::string& small_vt_store();

inline std::vector<std::uint8_t> file_bytes(const std::string& p) {
  std::ifstream f(p, std::ios::binary);
  return std::vector<std::uint8_t>(std::istreambuf_iterator<char>(f), {});
}
inline void put_file(const std::string& p, const std::vector<std::uint8_t>& b) {
  std::error_code ec;
  std::filesystem::remove(p, ec);
  std::ofstream f(p, std::ios::binary);
  f.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  REQUIRE(f.good());
}

// Every tile key of a store, in slot order.
inline std::vector<TileKey> all_keys(const TileStore& s) {
  std::vector<TileKey> k;
  for (std::uint64_t i = 0; i < s.geometry().tile_count(); ++i) k.push_back(s.geometry().key_of_slot(i));
  return k;
}

// The decoded texels of a tile, read synchronously (the reference the threaded paths must match).
inline std::vector<std::uint8_t> decoded(const TileStore& s, TileKey k) {
  AlignedBuffer scratch;
  std::vector<std::uint8_t> out(s.tile_bytes(k.layer()));
  s.read_tile(k, scratch, out.data(), out.size());
  return out;
}

// Polls `pred` until it holds or `seconds` pass; returns whether it held.
template <class Pred>
bool eventually(Pred pred, double seconds = 10.0) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return pred();
}

// The executor job that reads and decodes tile k of store s.
inline TileJob tile_job(const TileStore& s, RequestId id, TileKey k, std::uint64_t prio = 0) {
  const TileLocation loc = s.locate(k);
  return TileJob{id, k, loc.read_bytes, loc.decoded_bytes, prio};
}

// The IO pool's engines the IO-pool, fault and real-replay tests run on: psync, and io_uring where
// the kernel allows it (a seccomp filter, e.g. a container's, may refuse io_uring_setup; the
// fallback itself is tested by forcing the failure, test_io_pool.cpp).
inline const std::vector<IoEngine>& io_engines_here() {
  static const std::vector<IoEngine> engines = [] {
    std::vector<IoEngine> e{IoEngine::psync};
    if (io_uring_unavailable().empty()) e.push_back(IoEngine::io_uring);
    return e;
  }();
  return engines;
}

// An IO pool's config on `engine`, with `depth` reads in flight per worker on io_uring.
inline IoPoolConfig pool_config(IoEngine engine, int threads, int depth = 1, bool direct = true, bool verify = true) {
  IoPoolConfig c{threads, direct, verify};
  c.engine = engine;
  c.queue_depth = depth;
  return c;
}

// Runs `vtsim ARGS` with stderr through a file in `dir` (run_vtsim_capture).
inline CliRun run_cli(const RealScratch& dir, const std::string& args) {
  return run_vtsim_capture(args, dir.file("stderr.txt"));
}

}  // namespace vtsim::test
