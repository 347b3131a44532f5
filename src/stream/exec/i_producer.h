#pragma once
// The real clock's producer (docs/produced.md, "The real clock"): renders a produced tile
// (TileJob::produce.texels > 0, exec/produce.h) instead of reading it from the store. The
// threaded executor calls it on its production threads (ThreadedExecutorConfig::producer,
// produce_workers of them), in (priority, submission order), stamping decode_start / decode_end
// around the call; the simulated clock times the same work with ProduceModel.
//
// Thread-safety contract: produce() is called concurrently from several threads, for different
// jobs: an implementation keeps per-thread scratch (e.g. one produce::Compositor per thread) and
// reads shared content (atlas, masks) only. It must not call back into the executor. Throwing fails
// the job (JobOutcome::failed, Fault::decode_error, the exception's message as the fault's).
#include "core/tile_data.h"
#include "stream/exec/i_executor.h"

namespace vtsim {

class ITileProducer {
 public:
  virtual ~ITileProducer() = default;
  // Renders job.key into `out` (out.key is set): side, channels, bytes and texels.
  virtual void produce(const TileJob& job, TileData& out) = 0;
  // A job that is not produced (produce.texels == 0) that the producer materialises anyway instead
  // of the store reading it: the terrain's brush mips in the real clock, held in memory
  // (terrain_producer.h). Called under the executor's lock: constant, cheap, no callbacks.
  virtual bool serves(const TileJob&) const { return false; }
};

}  // namespace vtsim
