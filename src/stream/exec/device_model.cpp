#include "stream/exec/device_model.h"

#include <algorithm>
#include <limits>

namespace vtsim {

const Registry<DevicePreset>& disk_presets() {
  // Round figures of typical devices; override any field in the config.
  static const Registry<DevicePreset> presets(
      "disk preset",
      {
          {"hdd", "7200 rpm disk: ~8 ms seek + rotation, ~150 MB/s sequential, one head", {8000.0, 150.0, 1}},
          {"sata_ssd", "SATA SSD: ~100 us read latency, 530 MB/s (SATA III limit), NCQ depth 32", {100.0, 530.0, 32}},
          {"nvme", "PCIe 3.0 x4 NVMe SSD: ~80 us read latency, ~3000 MB/s, deep queues", {80.0, 3000.0, 64}},
          {"optical", "2x Blu-ray (PS3-class): ~100 ms seek, 9 MB/s (72 Mbit/s), one head", {100000.0, 9.0, 1}},
          {"unconstrained", "instant and unlimited: for closed-form checks", {0.0, 0.0, 0}},
      });
  return presets;
}

DiskModel disk_model(const DiskConfig& c) {
  DiskModel d = disk_presets().at(c.preset).disk;
  if (c.latency_us >= 0) d.latency_us = c.latency_us;
  if (c.bandwidth_MBps >= 0) d.bandwidth_MBps = c.bandwidth_MBps;
  if (c.channels >= 0) d.channels = c.channels;
  if (c.queue_depth >= 1) d.queue_depth = c.queue_depth;
  return d;
}

double disk_throughput_Bps(const DiskModel& d, double bytes_per_request) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  const double bus = d.bandwidth_MBps > 0 ? d.bandwidth_MBps * 1e6 : inf;
  if (d.channels <= 0 || d.latency_us <= 0) return bus;
  // Each request slot completes one request per (latency + transfer); the bus caps the sum.
  const double per_request_s = d.latency_us * 1e-6 + (bus == inf ? 0.0 : bytes_per_request / bus);
  const double by_channels = static_cast<double>(disk_slots(d)) * bytes_per_request / per_request_s;
  return std::min(bus, by_channels);
}

double decode_throughput_Bps(const DecodeModel& m, double bytes_per_tile) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  if (m.workers <= 0) return inf;
  const double per_tile_s =
      m.per_tile_us * 1e-6 + (m.throughput_MBps > 0 ? bytes_per_tile / (m.throughput_MBps * 1e6) : 0.0);
  if (per_tile_s <= 0) return inf;
  return m.workers * bytes_per_tile / per_tile_s;
}

}  // namespace vtsim
