#pragma once
// The executor runs a tile's IO and decode: one interface, two clocks (docs/architecture.md).
// The simulated executor computes completion times from device models on an event queue; the
// threaded executor reads real files with O_DIRECT and decodes on std::thread workers. The
// pipeline's request state machine (stream/exec/pipeline.h) is the same for both.
//
// Contract: jobs are submitted at the current time; each submitted job yields exactly one
// JobResult from collect(), except a job whose cancel() returned true (it never started: no cost,
// no result). Results are delivered in (completion time, submission order).
#include <cstdint>
#include <memory>
#include <vector>

#include "core/tile_key.h"
#include "core/time.h"
#include "stream/exec/produce.h"

namespace vtsim {

using RequestId = std::uint64_t;

// Decoded tile payload (real clock only; defined by the threaded executor).
struct TileData;

struct TileJob {
  RequestId id = 0;
  TileKey key;
  std::uint64_t disk_bytes = 0;     // bytes read from disk (codec model or the store's index)
  std::uint64_t decoded_bytes = 0;  // bytes after decode (what RAM and VRAM hold)
  std::uint64_t priority = 0;       // lower is served first (ties: submission order)
  ProduceWork produce{};            // a produced tile (produce.texels > 0): no read, no decode; disk_bytes 0
};

enum class JobOutcome : std::uint8_t {
  ready,      // read and decoded (a produced tile: produced)
  cancelled,  // cancelled after the read started: the read was paid, decode skipped
  failed,     // IO or decode fault (see fault)
};

enum class Fault : std::uint8_t { none, io_error, short_read, checksum, decode_error, bad_record };
const char* fault_name(Fault f);

struct JobResult {
  RequestId id = 0;
  TileKey key;
  JobOutcome outcome = JobOutcome::ready;
  Fault fault = Fault::none;
  Ticks submitted = 0;     // stage timestamps (ticks); a stage not reached repeats the previous one
  Ticks read_start = 0;    // a produced tile: read_start = read_end = submitted (no read)
  Ticks read_end = 0;
  Ticks decode_start = 0;  // a produced tile: production start and end
  Ticks decode_end = 0;    // = completion time for every outcome
  std::uint64_t bytes_read = 0;     // disk bytes actually read (0 if the read never started)
  std::uint64_t decoded_bytes = 0;
  std::shared_ptr<const TileData> data;  // real clock: the decoded tile; null in the simulated clock
};

class IExecutor {
 public:
  virtual ~IExecutor() = default;
  // Current time of this clock (ticks since the run started).
  virtual Ticks now() const = 0;
  // Jobs the pipeline may keep submitted (queued in the executor or under way): the IO pool's
  // bound on requests in flight. The pipeline holds the rest in its own priority queue.
  virtual std::size_t capacity() const = 0;
  virtual std::size_t in_flight() const = 0;
  virtual void submit(const TileJob& job) = 0;
  // true: the job had not started reading (a produced job: producing); it is dropped with no cost
  // and no result. false: it is under way; its result still arrives (cancelled if reading, ready
  // if decoding or producing).
  virtual bool cancel(RequestId id) = 0;
  // Simulated: runs every event up to and including `until`, then now() == until.
  // Real: `until` is the current wall time; returns what completed by then (never blocks).
  virtual void collect(Ticks until, std::vector<JobResult>& out) = 0;
};

}  // namespace vtsim
