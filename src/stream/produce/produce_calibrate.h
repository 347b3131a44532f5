#pragma once
// Calibrating the produce stage's cost model (exec/produce.h, ProduceModel) on this machine's CPU
// compositor (compositor.h), as `vtsim calibrate` does for the disk and the decoder
// (docs/produced.md, "Calibration").
//
//  - ProduceScene: procedural content to compose — brushes (value noise, RGBA8) built into an
//    Atlas with build_atlas, and 4 RGBA8 masks whose first `active` channels are non-zero
//    everywhere (so count_work's layers is exactly the layers asked for).
//  - measure_compositor: one Compositor on the calling thread, tiles of several sizes, borders,
//    layer counts and decal counts; per point the median of `repeats` timed compose() calls
//    (thread CPU time by default: a shared machine's other load does not count).
//  - fit_produce_model: per_tile_us, per_texel_ns, per_layer_texel_ns (and per_decal_us when the
//    samples vary the decals) by least squares on the relative error.
//
// Thread-safety: fit_produce_model is a pure function; ProduceScene::job() rewrites the scene's
// layer and mask descriptors (one thread at a time; the job it returns points into the scene), job_into
// is const (any number of threads);
// measure_compositor runs on the calling thread only.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "stream/exec/produce.h"
#include "stream/produce/atlas.h"
#include "stream/produce/compositor.h"

namespace vtsim::produce {

// One timed production: the work (as count_work counts it) and its wall time.
struct ProduceSample {
  std::uint64_t texels = 0;  // output texels with border
  std::uint32_t layers = 0;  // active layers blended
  std::uint32_t decals = 0;  // decals overlapping the tile
  double ns = 0;             // median wall time of one compose(), ns
  int tile = 0, border = 0;  // the job's T and B (for reports)
  std::uint64_t decal_texels = 0;  // output texels the decals touch, summed over them
};

// One tile a real-clock replay composed (TerrainProducer::record_tiles): its level, the work the
// system counted for it at submission (what the simulated clock's ProduceModel multiplies) and the
// time the composition took on its production thread — wall (steady clock: what the real clock's
// produce_ms counts, the executor's decode_start to decode_end less the queue hand-off) and that
// thread's CPU. `vtsim calibrate --samples` fits the [produce] keys to these (docs/produced.md,
// "Calibrating from the replay's own tiles").
struct ProducedTile {
  std::uint32_t level = 0;
  ProduceWork work;
  double wall_ns = 0, cpu_ns = 0;
};

// The CSV `vtsim replay --clock real --produce-samples` writes: a header line
// "level,texels,layers,decals,decal_texels,wall_us,cpu_us", then one row per tile.
std::string produced_tiles_csv(const std::vector<ProducedTile>& tiles);
// Reads that CSV. InputError naming the file, line and column on anything else: a missing or other
// header, a wrong field count, a field that is not a number, texels = 0, a time <= 0 or not finite.
std::vector<ProducedTile> read_produced_tiles_csv(const std::string& path);
// The tiles as fit samples, timed by their wall time (what the real clock's produce_ms counts) or
// their production thread's CPU time.
std::vector<ProduceSample> samples_from_tiles(const std::vector<ProducedTile>& tiles, bool cpu_time);

struct ProduceFit {
  ProduceModel model;             // base model with the fitted fields replaced
  bool decals_fitted = false;     // false: no decal variation in the samples; per_decal_us and per_decal_texel_ns kept from the base
  double median_rel_error = 0;    // |model - measured| / measured over the samples
  double max_rel_error = 0;
  bool relative = true;           // fitted on the relative error (the compositor's points) or the absolute one (a replay's tiles)
  double measured_ms = 0, model_ms = 0;  // the samples' sum and the model's for them (a replay's total production)
  std::vector<std::string> notes;  // dropped (negative) coefficients, degenerate columns
};

// Minimises sum(((model(s) - s.ns) / s.ns)^2) over per_tile_us, per_texel_ns, per_layer_texel_ns
// and, when decals vary, per_decal_texel_ns (when the samples count decal texels) and per_decal_us
// (when they count none, or the texels per decal differ between samples: else the two columns are
// proportional and the texels, the cost that grows with a decal, are fitted alone); a coefficient that would be negative is fixed at 0 and the
// rest refitted. workers and tiles_per_frame come from `base`. Throws InputError on fewer samples
// than unknowns, or samples with ns <= 0. O(samples).
// relative = false: the squared absolute error instead (ordinary least squares), for a replay's
// own tiles: their costs are noisy and skewed, and the relative fit then under-predicts their sum
// (−13 % on a walk's 1,870 tiles) where the absolute one, with its intercept, matches it exactly —
// and the sum is what production per frame adds up.
ProduceFit fit_produce_model(const std::vector<ProduceSample>& samples, const ProduceModel& base = {}, bool relative = true);

// Procedural content for the compositor: `brushes` value-noise brushes of side brush_side in an
// atlas (border 4 at every level: constant_border, 4 columns), and 4 masks of mask_side² RGBA8 texels covering mask_m metres whose
// channels 0..active-1 (over the 16) are in [16, 255] at every texel, the rest 0.
class ProduceScene {
 public:
  // `brushes` value-noise brushes of brush_side² (seeded).
  ProduceScene(int brushes, int brush_side, int active, int mask_side, double mask_m, std::uint64_t seed);
  // The given brushes (names[i] names brush i in errors: its file), in the same atlas; the masks as
  // above. InputError from build_atlas (a side not a power of two, sizes that differ, ...).
  ProduceScene(const std::vector<Rgba8>& brushes, const std::vector<std::string>& names, int active, int mask_side, double mask_m,
               std::uint64_t seed);
  const Atlas& atlas() const { return atlas_; }
  int active() const { return active_; }
  // A job of `layers` (<= active) brush layers of period_m, payload texel (0, 0) at (x_m, y_m), the
  // masks placed with their corner at (mask_x_m, mask_y_m).
  CompositeJob job(int layers, double period_m, double x_m, double y_m, double mask_x_m, double mask_y_m,
                   double m_per_texel, int tile, int border, std::span<const Decal> decals = {}) const;
  // The same job with its layer and mask descriptors written to the caller's arrays (the job points
  // into them and into the scene): const, so several threads may compose from one scene.
  CompositeJob job_into(std::span<BrushLayer, kMaxLayers> layer_out, std::span<WeightMask, kMaxLayers / 4> mask_out, int layers,
                        double period_m, double x_m, double y_m, double mask_x_m, double mask_y_m, double m_per_texel, int tile,
                        int border, std::span<const Decal> decals = {}) const;

 private:
  Atlas atlas_;
  int active_ = 0;
  int mask_side_ = 0;
  double mask_m_ = 0;
  std::vector<std::vector<std::uint8_t>> mask_texels_;
  // job() rewrites the layers' period and the masks' origin: call it from one thread at a time.
  mutable std::vector<BrushLayer> layers_;
  mutable std::vector<WeightMask> masks_;
};

struct ProduceMeasureOptions {
  std::vector<int> tiles = {128, 256, 512};     // payload sides T, texels
  std::vector<int> borders = {0, 4};            // B, texels
  std::vector<int> layers = {1, 2, 4, 8, 12, 16};
  std::vector<int> decals = {0, 16};            // decals overlapping each tile (counted by count_work)
  int repeats = 7;                              // timed compose() calls per point (median)
  int brush_side = 1024;                        // the terrain's brush mip 0 (terrain.brush_size)
  double m_per_texel = 1.0 / 1024;              // output texel, m (level 0 of the default terrain)
  std::uint64_t seed = 1;
  // Time the calling thread's CPU (CLOCK_THREAD_CPUTIME_ID) instead of the wall clock: the same on
  // an idle core, and not inflated by other tenants of a shared machine taking the core away.
  bool cpu_time = true;
};

// The calling thread's CPU time, ns (CLOCK_THREAD_CPUTIME_ID).
std::int64_t thread_cpu_ns();

using ProduceProgress = std::function<void(const std::string&)>;

// Times the compositor on this thread at every (tile, border, layers, decals) point. ~repeats x
// points x (T + 2B)^2 x layers x a few ns.
std::vector<ProduceSample> measure_compositor(const ProduceMeasureOptions& o, const ProduceProgress& progress = {});

// The [produce] section of a profile: the fitted keys with the samples and residuals as comments.
std::string produce_profile_toml(const ProduceFit& fit, const std::vector<ProduceSample>& samples);

}  // namespace vtsim::produce
