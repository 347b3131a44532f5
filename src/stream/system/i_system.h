#pragma once
// A streaming system decides what must be resident (clipmap windows, VT feedback pages) and holds
// VRAM residency; the pipeline moves tiles; the streaming runtime (stream/runtime/streaming_runtime.h)
// steps one system per frame, and the frame loop (sim/run/frame_loop.h) drives a runtime per run.
// Three systems implement this interface, one per file in stream/system/ and one line each in the
// systems' table (sim/run/systems.cpp): the clipmap (clipmap_system.h), sparse virtual texturing
// (vt_system.h) and the produced terrain (terrain_system.h); they share everything else.
//
// Call order, each frame (StreamingRuntime::plan_uploads, then commit_uploads):
//   begin_frame(f)                 the frame's pose and feedback; the system derives what it wants
//                                  (VT: the wanted pages; clipmap: the ground point it follows).
//   missing_bytes_by_level, coarsest_clamp, pool_occupancy, pool_pressure, pool_demand
//                                  what the throttle policy reads (const).
//   apply_throttle(d)              the policy's clamp and biases for this frame.
//   emit_needs(out)                appends this frame's needs: demand and prefetch, none resident.
//   per uploaded tile: accepts(key), vram_slot(key), then commit(key, frame) once the engine has
//                                  copied it (a refused tile is committed anyway: counted stale).
//   clip_windows(out)              the windows after the commits (the engine's window updates).
// The frame loop (SystemRun::step) measures pop-in through IResidency between the two halves:
// set_mark_sampled(false) and the lookups (resident_levels, span_resident_levels, fingerprint)
// before the commits, set_mark_sampled(true) and the lookups again after them; then it reads
// throttled_needs and frame_counters. stats_json, vram_evictions, vram_thrash and
// evicted_unsampled_bytes are read once, at the summary; the record_* opt-ins are set before the
// first frame or between frames.
//
// Threads: none of a system's members is thread-safe; one thread (the frame loop's, or the
// engine's render thread through the runtime) calls every member. The executor's IO, decode and
// production threads never call a system: they get tile keys and ProduceWork values, and the
// terrain's producer reads only its DecalLayer (decal_layer(): one writer, the system, and any
// number of readers; decal_layer.h). Render-ahead's workers render the view, never a system. A
// lockstep sweep's threads each step their own systems (sim/sweep/lockstep.h): a system is never
// touched by two threads, and the pop-in share they read together is the sweep's, not a system's.
//
// Complexity per frame (each system's header gives its own): VT O(S + W log W) for S feedback
// samples and W wanted pages; clipmap O(tiles of each moved or incomplete window level) plus
// O(S + T log T) to aggregate the feedback into T touched tiles when a need asks its importance;
// terrain as the clipmap plus O(missing window tiles × sectors per tile × brushes). commit and
// accepts O(1) expected; resident_level O(levels tried), O(1) amortised for VT. Nothing a system
// does per frame grows with the resident tiles beyond the windows or the wanted set.
#include <array>
#include <cstdint>
#include <glm/vec3.hpp>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "cache/i_residency.h"
#include "cache/need.h"
#include "cache/policy/access.h"
#include "core/time.h"
#include "core/trace.h"
#include "core/view.h"
#include "core/view_spans.h"
#include "stream/exec/produce.h"
#include "stream/throttle/i_throttle.h"

namespace vtsim {

// Per-frame counters a streaming system adds to the per-frame CSV (names from
// IStreamingSystem::frame_counter_names; unused entries stay 0).
inline constexpr std::size_t kSystemCounters = 12;
using SystemCounters = std::array<double, kSystemCounters>;

// What every streaming system is built from, whatever its kind: the texture and its tiles, where
// it lies on the ground, and the run's settings every system reads. Each system adds its own
// config section (ClipmapConfig, VtConfig); sim/run/systems.h makes both from the replay config.
struct SystemSetup {
  TextureExtent extent{1 << 20, 1 << 20};    // level-0 texels (the scene's texture)
  int tile_size = 128;                       // T, payload texels a side (VT: the page size P)
  int border = 0;                            // B, border texels a side (stored T + 2B)
  int layers = 1;                            // texture layers streamed per tile (albedo, normal, ...)
  std::uint64_t tile_bytes_all_layers = 0;   // decoded bytes of one tile, all layers summed
  double texels_per_m = 128.0;               // ground texel density at level 0
  double origin_x_m = 0.0, origin_y_m = 0.0; // world position of texel (0, 0), m
  double prefetch_lookahead_s = 0.0;         // look-ahead along the motion, s; 0 = off
  int thrash_frames = 60;                    // evicted then needed within this many frames = thrash
};

// A change of the page table the screen samples through (virtual texturing), in the order made:
// `page` (layer 0) maps to physical pool slot `slot`, or is unmapped (slot -1: samples fall back to
// its finest resident ancestor). What an engine mirrors into its page-table texture.
struct PageTableUpdate {
  TileKey page;
  std::int64_t slot = -1;
};

// A clipmap level's window (clip stack, Tanner 1998): origin and size in tiles of the level. Tile
// (x, y) of the window lives at toroidal slot (x mod w, y mod h) of the level's texture.
struct ClipWindow {
  std::int64_t x0 = 0, y0 = 0, w = 0, h = 0;
  bool operator==(const ClipWindow&) const = default;
};

struct SystemFrame {
  int frame = 0;
  Ticks now = 0;
  const Pose* pose = nullptr;
  glm::dvec3 velocity_mps{0.0};    // camera velocity (zero across a cut)
  const ViewBuffer* view = nullptr;  // feedback of this frame (may be an earlier frame's, see view.feedback_every)
  int finest_needed = 0;           // finest desired level of any sample (num_levels: nothing visible)
  const SpanBuffer* spans = nullptr;  // the same feedback in run-length form (systems that use_spans)
};

class IStreamingSystem : public IResidency {
 public:
  // Per frame, in this order.
  virtual void begin_frame(const SystemFrame& f) = 0;
  virtual void missing_bytes_by_level(std::vector<std::uint64_t>& out) const = 0;
  virtual int coarsest_clamp() const = 0;   // the clamp that means "coarsest fallback only"
  virtual void apply_throttle(const ThrottleDecision& d) = 0;
  virtual void emit_needs(std::vector<Need>& out) = 0;  // demand and prefetch, not resident
  // Counts tiles the clamp kept from being needed in the last emit_needs.
  virtual std::uint32_t throttled_needs() const = 0;
  // An uploaded tile becomes resident; false if it is no longer wanted (stale).
  virtual bool commit(TileKey key, int frame) = 0;
  // Whether commit(key, ...) would accept the tile now (true) or find it stale (false): exactly
  // commit's answer, without its effects. The streaming runtime asks it before handing a tile to
  // the engine's upload, and commits only once the upload returned.
  virtual bool accepts(TileKey key) const = 0;
  // Where a tile that commit() accepts (or just accepted) lives in VRAM: its physical pool slot (virtual
  // texturing: every layer of a page shares one slot), or -1 when the key alone places it (the
  // clipmap's toroidal windows). The real clock copies the tile's texels there.
  virtual std::int64_t vram_slot(TileKey) const { return -1; }
  // A produced tile (stream/exec/produce.h): true and its work when `key` is rendered by a
  // producer instead of read from the store. Systems that only stream return false.
  virtual bool produced(TileKey /*key*/, ProduceWork& /*work*/) const { return false; }
  // A produced system: true and the work of one full tile of the finest level (decals aside:
  // sparse), which sets the production stage's service rate for throttling (SystemRun::service_Bps).
  virtual bool full_tile_work(ProduceWork& /*work*/) const { return false; }
  // A tile whose sizes the system sets itself instead of the texture's layers (the terrain's brush
  // mips, streamed from disk to render produced tiles): true and its disk and decoded bytes.
  virtual bool tile_sizes(TileKey /*key*/, std::uint64_t& /*disk_bytes*/, std::uint64_t& /*decoded_bytes*/) const {
    return false;
  }
  virtual void set_mark_sampled(bool on) = 0;
  // True when the system reads SystemFrame::spans and resolves spans (span_resident_levels); the
  // frame loop then renders spans only. Otherwise it also passes the per-sample buffer (`view`).
  virtual bool uses_spans() const { return false; }
  // True when the next begin_frame will read every sample although the system uses spans (a VT
  // feedback bias): the frame loop then materialises the span buffer's samples once
  // (materialise_samples) and passes them as `view`, and every later expansion is a copy.
  virtual bool wants_samples() const { return false; }
  virtual double pool_occupancy() const { return 0.0; }
  virtual double pool_pressure() const { return 0.0; }
  // Virtual texturing: pages wanted per level and pool slots (ThrottleInput); clipmaps: none.
  virtual void pool_demand(std::vector<std::uint64_t>& pages_by_level, std::uint64_t& slots) const {
    pages_by_level.clear();
    slots = 0;
  }
  // System-specific per-frame counters for the per-frame CSV (names once, values every frame).
  virtual std::vector<std::string> frame_counter_names() const { return {}; }
  virtual void frame_counters(SystemCounters& out) const { out.fill(0.0); }
  // The pages complete in a physical page pool, each with its slot (what a page table maps: the
  // real clock checks its VRAM arena against them); empty for a system without a pool.
  virtual void pool_pages(std::vector<std::pair<TileKey, std::uint32_t>>& out) const { out.clear(); }
  // Opt-in: from now on, every change of the page table (map, unmap) appends a PageTableUpdate to
  // `log`, in order; null stops. A system without a page table records nothing.
  virtual void record_page_table(std::vector<PageTableUpdate>* /*log*/) {}
  // Each level's clipmap window, finest level first; empty for a system without windows.
  virtual void clip_windows(std::vector<ClipWindow>& out) const { out.clear(); }
  // Opt-in: from now on, every page of the pool this system wants each frame appends an Access
  // {page key bits, 1} to `log`, and each frame opens a frame in it (docs/metrics.md, "Pool hits
  // and misses"). Null stops. A system without a pool records nothing.
  virtual void record_pool_accesses(AccessLog* /*log*/) {}
  // System-specific counters for the summary ("clipmap" or "vt" section), and the VRAM totals.
  virtual nlohmann::json stats_json() const = 0;
  virtual std::uint64_t vram_evictions() const = 0;
  virtual std::uint64_t vram_thrash() const = 0;
  virtual std::uint64_t evicted_unsampled_bytes() const = 0;
};

}  // namespace vtsim
