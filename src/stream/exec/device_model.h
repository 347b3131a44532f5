#pragma once
// Device models for the simulated clock (docs/pipeline.md, "The simulated clock"): a disk, a
// decode stage and an upload link. Each is a few numbers with presets; the simulated executor
// turns them into completion times on the event queue. A calibrated profile (`vtsim calibrate`)
// fills the same structs.
#include <cstdint>
#include <string>
#include <vector>

#include "core/time.h"

namespace vtsim {

// Disk: `channels` requests in service at once (the device's internal parallelism / queue depth).
// A request first spends `latency_us` (seek, command, flash read — overlapped across channels),
// then its bytes cross one shared transfer bus of `bandwidth_MBps`, first come first served.
// So one request alone takes latency + bytes/bandwidth, and many saturate at the bandwidth.
struct DiskModel {
  double latency_us = 80.0;        // per-request latency before transfer, microseconds
  double bandwidth_MBps = 3000.0;  // shared transfer bandwidth, MB/s (10^6 B/s); 0 = unlimited
  int channels = 32;               // requests in service concurrently; 0 = unlimited
};

// Decode: `workers` identical servers; a tile takes per_tile_us + decoded_bytes / throughput.
struct DecodeModel {
  double throughput_MBps = 0.0;  // decoded output per worker, MB/s; 0 = free (raw tiles)
  double per_tile_us = 0.0;      // fixed cost per tile (codec setup, checksums), microseconds
  int workers = 2;               // decode threads; 0 = unlimited
};

// Upload to VRAM: a per-frame budget (bytes and/or tiles; 0 = unlimited) over a link of finite
// bandwidth. Uploads issued in a frame are visible in that frame; the link caps a frame's bytes at
// link bandwidth x frame period.
struct UploadModel {
  std::uint64_t bytes_per_frame = 0;  // budget, bytes per frame; 0 = unlimited
  int tiles_per_frame = 16;           // budget, tiles per frame; 0 = unlimited (Unity Clipmap: MaxUploadsPerFrame)
  double link_MBps = 12000.0;         // host -> VRAM link bandwidth, MB/s; 0 = unlimited (~PCIe 3.0 x16)
};

struct DevicePreset {
  std::string name;
  std::string why;  // what it stands for, with the source of its figures
  DiskModel disk;
};

// hdd, sata_ssd, nvme, optical, unconstrained (instant, unlimited: for closed-form checks).
const std::vector<DevicePreset>& disk_presets();
const DevicePreset* find_disk_preset(const std::string& name);

// Sustainable bytes/s of the disk for requests of `bytes` each (Little's law over the channels,
// capped by the bus): used by throttling to predict how long a backlog takes.
double disk_throughput_Bps(const DiskModel& d, double bytes_per_request);
double decode_throughput_Bps(const DecodeModel& m, double bytes_per_tile);

}  // namespace vtsim
