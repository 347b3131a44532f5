#pragma once
// Device models for the simulated clock (docs/pipeline.md, "The simulated clock"): a disk, a
// decode stage and an upload link. Each is a few numbers with presets; the simulated executor
// turns them into completion times on the event queue. A calibrated profile (`vtsim calibrate`)
// fills the same structs.
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "core/registry.h"
#include "core/time.h"

namespace vtsim {

// Disk: `channels` submitters (the real clock's IO threads), each with up to `queue_depth`
// requests in service (1: one pread at a time, as psync; io_uring: the ring's depth), so
// channels x queue_depth requests are in service at once (disk_slots). A request first spends
// `latency_us` (seek, command, flash read — overlapped across requests in service), then its bytes
// cross one shared transfer bus of `bandwidth_MBps`, first come first served. So one request alone
// takes latency + bytes/bandwidth, many saturate at the bandwidth, and at depth d a request's
// service time grows as the bus queue ahead of it (calibrate measures it against depth).
struct DiskModel {
  double latency_us = 80.0;        // per-request latency before transfer, microseconds
  double bandwidth_MBps = 3000.0;  // shared transfer bandwidth, MB/s (10^6 B/s); 0 = unlimited
  int channels = 32;               // submitters with requests in service; 0 = unlimited
  int queue_depth = 1;             // requests in service per channel (io.queue_depth with io_uring)
};
// Requests in service at once: channels x queue_depth; 0 = unlimited.
inline long long disk_slots(const DiskModel& d) {
  return d.channels <= 0 ? 0 : static_cast<long long>(d.channels) * (d.queue_depth > 0 ? d.queue_depth : 1);
}

// Decode: `workers` identical servers; a tile takes per_tile_us + decoded_bytes / throughput.
struct DecodeModel {
  double throughput_MBps = 0.0;  // decoded output per worker, MB/s; 0 = free (raw tiles)
  double per_tile_us = 0.0;      // fixed cost per tile (codec setup, checksums), microseconds
  int workers = 2;               // decode threads; 0 = unlimited
};

// Upload to VRAM: a per-frame budget (bytes and/or tiles) over a link of finite bandwidth. Uploads
// issued in a frame are visible in that frame; the link caps a frame's bytes at link bandwidth x
// frame period. The fields are the config's [upload] section. A tile's copy (the latency stage
// "upload") takes per_tile_us + bytes / link_MBps (upload_ticks); with per_tile_us > 0 the link
// caps a frame's copies at one frame period of that time instead of its bytes.
struct UploadModel {
  int tiles_per_frame = 16;              // budget, tiles per frame; -1 = no tile limit (Unity Clipmap: MaxUploadsPerFrame)
  std::int64_t bytes_per_frame = -1;     // budget, bytes per frame; -1 = no byte limit
  double link_MBps = 12000.0;            // host -> VRAM link bandwidth, MB/s; 0 = unlimited (~PCIe 3.0 x16)
  double per_tile_us = 0.0;              // fixed cost of one tile's copy (map, submit, driver), us (vtsim gl calibrate-upload)
};
// One tile's copy over the link, ticks: per_tile_us (rounded to the nanosecond) + bytes / link_MBps
// (rounded up; 0 when the link is unlimited).
inline Ticks upload_ticks(const UploadModel& m, std::uint64_t bytes) {
  const Ticks fixed = static_cast<Ticks>(m.per_tile_us * 1000.0 + 0.5);
  return fixed + transfer_ticks(bytes, m.link_MBps * 1e6);
}

// A disk preset: a named DiskModel with what it stands for.
struct DevicePreset {
  std::string_view name;
  std::string_view why;  // what it stands for, with the source of its figures
  DiskModel disk;
};

// hdd, sata_ssd, nvme, optical, unconstrained (instant, unlimited: for closed-form checks).
// Adding a preset is one line in device_model.cpp.
const Registry<DevicePreset>& disk_presets();

// The config's [disk] section: a preset, and any of its fields overridden (-1 = the preset's).
struct DiskConfig {
  std::string preset = "nvme";     // a name of disk_presets()
  double latency_us = -1.0;        // per-request latency, us; -1 = the preset's
  double bandwidth_MBps = -1.0;    // shared transfer bandwidth, MB/s; 0 = unlimited; -1 = the preset's
  int channels = -1;               // requests in service at once; 0 = unlimited; -1 = the preset's
  int queue_depth = -1;            // requests in service per channel; -1 or 0 = the preset's (1)
};
// The preset with the overrides applied. Throws std::invalid_argument (Registry::at) for an
// unknown preset.
DiskModel disk_model(const DiskConfig& c);

// Sustainable bytes/s of the disk for requests of `bytes` each (Little's law over the channels,
// capped by the bus): used by throttling to predict how long a backlog takes.
double disk_throughput_Bps(const DiskModel& d, double bytes_per_request);
double decode_throughput_Bps(const DecodeModel& m, double bytes_per_tile);

}  // namespace vtsim
