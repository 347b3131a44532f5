#pragma once
// Simulated executor: tile reads and decodes timed by device models on an event queue of integer
// ticks. Deterministic: the same submissions at the same times give the same results bit for bit.
//
// Disk (DiskModel): up to channels x queue_depth jobs in service (disk_slots); queued jobs start by
// (priority, submission order) when a slot frees. A job spends latency_us, then transfers over one shared bus
// (first come first served), then frees its channel. Decode (DecodeModel): `workers` servers,
// queued by (priority, submission order). Production (ProduceModel, stream/exec/produce.h): a
// produced job (TileJob::produce) skips the disk and the decode — no latency, no bus, no IO fault,
// read_start = read_end = its submission — and waits for one of the model's `workers` servers, by
// (priority, submission order), for round(produce_ns(model, work)) ticks; decode_start/decode_end
// are its production. Cancel as for reads: not started, dropped at no cost; producing, it finishes
// as ready. Complexity: O(log n) per event. Single-threaded.
#include <map>
#include <set>
#include <unordered_map>

#include "stream/exec/event_queue.h"
#include "stream/exec/device_model.h"
#include "stream/exec/fault_layer.h"
#include "stream/exec/i_executor.h"
#include "stream/exec/produce.h"

namespace vtsim {

// Injected faults, the same decisions as the real clock's fault layer (stream/exec/fault_layer.h):
// deterministic per (seed, tile, attempt), so runs stay reproducible and a retry may succeed. An
// IO error fails the job when its transfer ends (bytes counted as read), a short read fails it
// there with half the bytes, a corrupted payload fails it as `checksum` when its decode ends, and
// a slow read adds its delay to the read's latency.
using SimFaultModel = FaultConfig;

class SimExecutor final : public IExecutor {
 public:
  SimExecutor(const DiskModel& disk, const DecodeModel& decode, std::size_t capacity,
              SimFaultModel faults = {}, const ProduceModel& produce = {});

  Ticks now() const override { return now_; }
  std::size_t capacity() const override { return capacity_; }
  std::size_t in_flight() const override { return jobs_.size(); }
  void submit(const TileJob& job) override;
  bool cancel(RequestId id) override;
  void collect(Ticks until, std::vector<JobResult>& out) override;

  // Busy time accounting for utilisation metrics.
  Ticks disk_busy_ticks() const { return bus_busy_; }
  // Production servers' busy time, summed over the servers (ticks; cancelled jobs never started).
  Ticks produce_busy_ticks() const { return produce_busy_; }
  // A produced tile's production time under the model, ticks (produce_ns rounded to the nearest).
  static Ticks produce_ticks(const ProduceModel& m, const ProduceWork& w);

 private:
  enum class Stage : std::uint8_t { disk_queue, disk_latency, disk_transfer, decode_queue, decoding, produce_queue, producing };
  struct Job {
    TileJob job;
    Stage stage = Stage::disk_queue;
    bool cancelled = false;
    std::uint64_t seq = 0;  // submission order
    FaultPlan faults;       // drawn when the read starts
    JobResult result;
  };
  enum class Ev : std::uint8_t { latency_done, transfer_done, decode_done, produce_done };
  struct Event {
    Ev kind;
    RequestId id;
  };
  using QueueKey = std::pair<std::uint64_t, std::uint64_t>;  // (priority, seq)

  void start_disk_jobs();
  void start_decode_jobs();
  void start_produce_jobs();
  void finish(Job& j, std::vector<JobResult>& out);

  DiskModel disk_;
  DecodeModel decode_;
  ProduceModel produce_;
  std::size_t capacity_;
  FaultLayer faults_;
  Ticks now_ = 0;
  Ticks bus_free_ = 0;   // when the shared transfer bus is next idle
  Ticks bus_busy_ = 0;
  int disk_active_ = 0;
  int decode_active_ = 0;
  int produce_active_ = 0;
  Ticks produce_busy_ = 0;
  std::uint64_t next_seq_ = 0;
  std::unordered_map<RequestId, Job> jobs_;
  std::map<QueueKey, RequestId> disk_queue_, decode_queue_, produce_queue_;
  EventQueue<Event> events_;
};

}  // namespace vtsim
