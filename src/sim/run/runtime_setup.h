#pragma once
// A streaming runtime (stream/runtime/streaming_runtime.h) from a replay config: the parts both
// replays' SystemRun and an engine's runtime are built from, so the three stream one way.
#include <memory>

#include "sim/run/replay_config.h"
#include "stream/exec/threaded_executor.h"
#include "stream/runtime/streaming_runtime.h"
#include "stream/store/tile_store.h"

namespace vtsim {

// The system run.system names over `extent`, the throttle policy throttle.policy, the pipeline's
// [ram] and [io] settings, the upload budget ([upload], the link over one frame of `period_s`) and
// the service rate the throttle plans with. `executor` null: a simulated executor from the
// config's device models, owned by the parts. `sizer` null: tile sizes from the config's layers.
// Throws InputError for a config the registries refuse.
RuntimeParts runtime_parts(const ReplayConfig& cfg, TextureExtent extent, double period_s, IExecutor* executor, TileSizer sizer);

struct EngineRuntimeOptions {
  // The executor's pools and queue; default: from the config's [io], [decode] and [ram].
  bool threads_from_config = true;
  ThreadedExecutorConfig executor;
};

// An engine's runtime over a tile store, in the real clock: the config's texture is bound to the
// store (bind_store_texture: a store that does not match the config is refused with InputError
// naming the field, before any frame), a ThreadedExecutor on the store (io.threads IO threads,
// decode.workers decode threads) owned by the runtime, frames of 1 / run.fps seconds. Stored
// systems only (clipmap, vt; InputError for the terrain, whose tiles are produced). Time is the
// executor's: begin_frame(rt->executor().now()).
std::unique_ptr<StreamingRuntime> make_streaming_runtime(ReplayConfig cfg, const TileStore& store,
                                                         const EngineRuntimeOptions& options = {});

}  // namespace vtsim
