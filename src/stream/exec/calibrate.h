#pragma once
// `vtsim calibrate`: measures this machine on a tile store and fits the simulated clock's device
// models to it (docs/real-engine.md §5), so the simulated clock predicts the real one.
//
//  - Disk: O_DIRECT reads of the store file at random 4 KiB-aligned offsets of its data region,
//    by request size and by reads in flight, with the IO pool's engine: psync (threads each with
//    one pread in flight) or io_uring (io_threads threads, each with its own ring at depth 1, 4,
//    16, 32 and io.queue_depth: service time against depth); latency percentiles and aggregate
//    bandwidth per point.
//  - Decode: the store's own tiles (a sample per layer), verify + decode as the decode pool does,
//    per codec on one worker, then the decode pool's throughput by worker count.
//  - Fit: DiskModel{latency_us, bandwidth_MBps, channels = io threads, queue_depth = 1 or
//    io.queue_depth} (fit_disk_model) and
//    DecodeModel{per_tile_us, throughput_MBps, workers} (per-tile cost at the pool's measured speed).
//
// Takes ~seconds_per_point × (sizes × concurrencies + workers) of wall time. Not thread-safe
// (spawns its own threads).
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "stream/exec/device_model.h"
#include "stream/exec/io_engine.h"
#include "stream/store/tile_store.h"

namespace vtsim {

struct CalibrateOptions {
  int io_threads = 4;                 // the IO pool's threads the profile is for (io.threads)
  int decode_workers = 2;             // the decode pool's workers the profile is for (decode.workers)
  bool direct = true;                 // O_DIRECT (io.direct)
  double seconds_per_point = 0.4;     // measuring time of each (size, concurrency) and decode point
  std::vector<std::uint32_t> sizes;   // request sizes, bytes (multiples of 4096); empty = defaults
  std::vector<int> concurrency;       // psync: empty = 1, 2, 4, 8 and io_threads
  IoEngine engine = IoEngine::psync;  // the IO pool's engine the profile is for (io.engine)
  int queue_depth = 16;               // io_uring: reads in flight per thread (io.queue_depth)
  std::vector<int> depths;            // io_uring: depths measured, io_threads threads each; empty = 1, 4, 16, 32 and queue_depth
  int fail_ring_errno = 0;            // test hook: io_uring setup fails with this errno (io_pool.h)
  std::uint32_t decode_sample = 48;   // tiles per layer sampled for decode
  std::uint64_t seed = 1;
};

struct ReadPoint {
  std::uint32_t bytes = 0;  // request size
  int concurrency = 0;      // reads in flight (threads x depth)
  int depth = 1;            // reads in flight per thread (io_uring; psync: 1)
  std::uint64_t reads = 0;
  double MBps = 0;          // aggregate, MB/s
  double p50_us = 0, p95_us = 0, p99_us = 0, mean_us = 0;  // per-read latency
};

struct DecodePoint {
  std::string what;   // "layer albedo (zstd)" or "pool"
  int workers = 0;
  std::uint64_t tiles = 0;
  double us_per_tile = 0;      // mean wall time per tile per worker
  double tiles_per_s = 0;      // aggregate
  double decoded_MBps = 0;     // aggregate decoded MB/s
  double stored_bytes = 0;     // mean stored bytes per tile
  double decoded_bytes = 0;    // mean decoded bytes per tile
};

struct Calibration {
  std::vector<ReadPoint> reads;
  std::vector<DecodePoint> decodes;
  double mean_read_bytes = 0;  // the store's mean aligned read, bytes (the fit's request size)
  DiskModel disk;
  DecodeModel decode;
  int io_threads = 0;
  IoEngine engine = IoEngine::psync;  // what was measured (psync after an io_uring fallback)
  int queue_depth = 1;                // per thread: 1 with psync
  std::string engine_warning;         // why io_uring was not used, or empty
  bool direct = false;
  std::string direct_warning;
  std::vector<std::string> notes;  // how the fit went (residuals, fallbacks)
};

using CalibrateProgress = std::function<void(const std::string&)>;

// Throws InputError for bad options (sizes not multiples of 4096, larger than the data region...).
Calibration calibrate(const TileStore& store, const CalibrateOptions& options, const CalibrateProgress& progress = {});

// The disk fit: DiskModel{latency_us, bandwidth_MBps, channels = io_threads} (io_threads: the most
// reads in flight, threads x queue depth) minimising the squared log error of the model's
// throughput (disk_throughput_Bps with each point's concurrency as its channels) against the
// measured points with concurrency <= io_threads; points of
// `typical_bytes` (the store's mean read) weigh 4x. Residuals per point go to `notes`.
DiskModel fit_disk_model(const std::vector<ReadPoint>& points, int io_threads, std::uint32_t typical_bytes,
                         std::vector<std::string>* notes = nullptr);

// The device profile: a TOML file of config keys (disk.*, decode.*, io.threads, io.direct, io.engine,
// io.queue_depth) with the
// measurements as comments; usable as `--config` or merged with `--set`.
std::string profile_toml(const Calibration& c, const std::string& store_path);

}  // namespace vtsim
