#pragma once
// What a streaming system can do, stated by its class (static kName and kCaps) and carried by its
// entry in the systems' table (sim/run/systems.h): the command line and the frame loop ask these
// instead of comparing system names. Plain constants; thread-safe.
#include <string_view>

namespace vtsim {

// The report `vtsim capacity --system <name>` prints for a system.
enum class CapacityReport {
  window_stack,  // a clipmap's stack and pyramid against a full mip chain (docs/clipmap.md)
  page_pool,     // a virtual texture's disk size, page table and the pool a screen needs (docs/vt.md)
  produced,      // a produced clipmap's stored brushes and masks and the brushes resident (docs/produced.md)
};

struct SystemCaps {
  // Composes its tiles from brushes and masks (the produce stage): in the real clock it reads no
  // tile store, its producer serves them from memory.
  bool produces_tiles = false;
  // Holds a physical page pool behind a page table: a cache level of its own that `vtsim mrc`
  // and metrics.opt replay, and the only kind a feedback replay (--feedback) drives.
  bool page_pool = false;
  // Moves clipmap windows (clip_windows) sized by [clipmap].
  bool clip_window = false;
  CapacityReport capacity = CapacityReport::window_stack;
  // The cache level `vtsim mrc --trace` reads when --level is not given: "ram" or "pool".
  std::string_view mrc_level = "ram";
};

}  // namespace vtsim
