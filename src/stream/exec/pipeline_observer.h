#pragma once
// What a request pipeline tells an observer (opt-in: Pipeline::set_observer; the tile timeline,
// sim/run/timeline.h, is one). Each call happens on the pipeline's thread, inside the pipeline
// call named, and sees the state the counters count: every demand request (PipelineCounters::
// requests) is one on_request, every job the executor returns (each disk read and decode,
// cancelled and look-ahead ones included: disk_reads, decodes) one on_job, every demand request
// that ends without its upload one on_unserved. Without an observer the pipeline pays a null
// check at each of these points, nothing else.
#include "core/tile_key.h"
#include "core/time.h"
#include "stream/exec/i_executor.h"

namespace vtsim {

enum class Unserved : std::uint8_t;

class IPipelineObserver {
 public:
  virtual ~IPipelineObserver() = default;
  // set_needs: a demand request for `key` starts at (frame, now): the first need of a tile not
  // resident, or a look-ahead fetch under way that became a demand. `ram_hit`: served from the
  // RAM cache (waiting for upload at once); `produced`: a produced tile (no read).
  virtual void on_request(TileKey key, int frame, Ticks now, bool ram_hit, bool produced) = 0;
  // begin_frame / dispatch: the executor returned a job (its stage times; `prefetch`: a
  // look-ahead fetch nobody waits for yet; `produced`: a produced tile's job, no read or decode).
  virtual void on_job(const JobResult& r, bool prefetch, bool produced) = 0;
  // A demand request ended without being uploaded: `end` when it stopped being needed (cancelled)
  // or was given up (failed). Requests still open at the run's end are not reported.
  virtual void on_unserved(TileKey key, Ticks end, Unserved why) = 0;
};

}  // namespace vtsim
