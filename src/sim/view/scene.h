#pragma once
// Scenes the feedback renderer draws (docs/view.md), one table of them (scenes()): a flat ground
// plane, a heightfield, an OBJ mesh with unique UVs (Yao 2011's megatexture case) and a generated
// test town. Every scene is
// parameterised into one virtual texture and renders a ViewBuffer: one ViewSample per feedback
// pixel whose nearest surface within [near, far] faces the camera and lies inside the texture.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/camera.h"
#include "core/registry.h"
#include "core/view.h"
#include "core/view_spans.h"
#include "sim/view/gpu_model.h"

namespace vtsim {

class IScene : public ISampleSource {
 public:
  // The level-0 virtual texture the scene is parameterised into.
  virtual TextureExtent texture() const = 0;
  // Renders one feedback frame into `out` (cleared first; its storage is reused, so a caller
  // that keeps one ViewBuffer per thread renders without allocating after the first frame).
  // Thread-safe: render may run concurrently on one scene object from several threads.
  // Throws InputError for invalid ViewParams (validate_view_params).
  virtual void render(const Camera& cam, const ViewParams& params, ViewBuffer& out) const = 0;

  // Renders one frame in run-length form (view_spans.h): spans, counters and sample count equal
  // spans_from_samples of render()'s buffer exactly. `out`'s block_shift and keep_samples are
  // the caller's. The default renders per sample (so has_samples is true) and derives the spans;
  // a scene with a faster span renderer overrides this and render_pixels. Thread-safe; no
  // allocation after warm-up. Throws like render, and std::invalid_argument for a bad block_shift.
  virtual void render_spans(const Camera& cam, const ViewParams& params, SpanBuffer& out) const;

  // Appends render()'s samples of the `count` buffer pixels from `pixel` of the frame `sb` holds
  // (its camera and parameters; a mesh also reads its faces, SpanBuffer::surface): one row, a
  // span's pixels, so every one of them is a sample (std::logic_error otherwise). Needed only by
  // scenes whose render_spans leaves has_samples false; the default throws std::logic_error.
  void render_pixels(const SpanBuffer& sb, std::uint32_t pixel, std::uint32_t count,
                     std::vector<ViewSample>& out) const override;

  // The surface the ray through full-resolution pixel position (px, py) meets first, classified
  // as render() classifies a sample, with its plane and affine texel map (gpu_model.h: the GPU
  // feedback model extrapolates a quad partner's texel coordinates on it). The default throws
  // std::logic_error (a scene the GPU model does not draw).
  virtual void surface_at(const Camera& cam, const ViewParams& params, double px, double py, SurfaceHit& hit) const;

  // What the scene's reader left out of its input file, one line each naming the file and the
  // count ("town.obj: 3 of 1200 triangles skipped: zero area"), for the CLI to print as warnings;
  // empty for a scene that read everything (and for every generated scene).
  virtual std::vector<std::string> load_warnings() const { return {}; }

  // The ground's height under world (x, y), to place a camera above it (`vtsim view --agl`): NaN
  // where the scene has ground but not there; nullopt for a scene without one ground surface.
  virtual std::optional<double> ground_z(double /*x_m*/, double /*y_m*/) const { return std::nullopt; }
};

// Parameters of make_scene. Every scene maps into one virtual texture of
// llround(size_x_m·texels_per_m) × llround(size_y_m·texels_per_m) level-0 texels.
struct SceneConfig {
  std::string kind = "plane";      // a name of scenes()
  std::string file;                // the scene's input file: heightfield image, OBJ mesh (scenes()'s `file`)

  // The terrain and its texture. Defaults: 8192 m × 8192 m at 128 texels/m = a 2^20 × 2^20
  // virtual texture, the megatexture scale of Yao 2011 (RAGE: 128k², here 8× larger a side).
  double size_x_m = 8192.0;        // terrain extent along world x, metres
  double size_y_m = 8192.0;        // along world y
  double texels_per_m = 128.0;     // level-0 texel density on the ground (0.78 cm texels)
  double origin_x_m = 0.0;         // world x of texel u = 0 (terrain: u = floor((x − x0)·tpm))
  double origin_y_m = 0.0;         // world y of texel v = 0

  // plane: the ground z = plane_z_m.
  double plane_z_m = 0.0;

  // heightfield: posts on a regular grid from the terrain origin; z = z0 + scale·value.
  //   `file`: any image OpenImageIO reads (first channel); empty: noise
  double spacing_m = 8.0;          // between posts; 8 m × 1024 cells spans the default terrain
  double height_scale_m = 200.0;   // metres per image value (OIIO maps integer pixels to [0, 1]): a full-range sample
  double z0_m = 0.0;               // height of value 0
  int noise_posts = 1025;          // generated grid is noise_posts² (2^10 cells + 1: one post per 8 m)
  double noise_amplitude_m = 150.0;  // generated relief, peak to mean: hills that occlude each other
  std::uint64_t seed = 1;          // generated heightfield and town

  // mesh: `file` is a scene file (mesh_import.h, docs/view.md "Scenes"). An OBJ read by the
  // hand-written reader: vt (u, v) in [0, 1) spans the whole virtual texture. Through assimp:
  // each material gets a power-of-two square region, its UVs wrapped into it.
  std::string mesh_loader = "auto";  // "auto" (obj for .obj, else assimp), "assimp", "obj"
  double mesh_unit_m = 1.0;          // assimp: metres per file unit (Quake 3: 0.0254)
  std::string mesh_up = "auto";      // assimp: file's up axis, "auto" (y: glTF/FBX/Collada; z: others), "y", "z"
  int mesh_uv_set = 0;               // assimp: UV channel (Quake 3: 0 texture, 1 lightmap)
  std::string mesh_no_uv = "untextured";  // assimp: parts without UVs: "untextured", "skip", "planar", "error"
  double mesh_planar_m = 1.0;        // assimp, mesh_no_uv = "planar": metres per UV period

  // town (generated mesh): a grid of city blocks on ground z = 0 from the terrain origin.
  int town_blocks = 16;            // blocks per side
  double town_block_m = 60.0;      // block edge, metres (2×2 lots of buildings)
  double town_street_m = 16.0;     // street width, metres
  double town_max_height_m = 40.0; // tallest building; heights are uniform in [6 m, max]
  int town_walls_per_block = 2;    // free-standing walls (3 m high) per block: near occluders
};

enum class SceneFile { none, height_image, mesh };

// A kind of scene in the table (scene.cpp): adding a scene is its file (a class implementing
// IScene and its make function) and one line in the table.
struct SceneInfo {
  std::string_view name;
  std::string_view why;
  // What SceneConfig::file is for this scene ("" = none is read); with file_required, a scene
  // without one is refused.
  std::string_view file;
  bool file_required = false;
  // Builds the scene (extent: scene_texture(cfg)); throws InputError naming the field or file.
  std::unique_ptr<IScene> (*make)(const SceneConfig& cfg, TextureExtent extent);
  // What kind of file `file` is, for commands whose flags predate scene.file (view's --obj, --heightmap).
  SceneFile file_kind;
  // Where a scene laid out at a fixed size from the texture's origin lies (the town), and a trace
  // that walks in it, for the hint when no frame saw a surface; nullptr: it covers the texture.
  std::string (*where)(double origin_x_m, double origin_y_m);
};
const Registry<SceneInfo>& scenes();
// The scene of that name; throws InputError("scene", "unknown scene ... did you mean ...").
const SceneInfo& find_scene(std::string_view name);

// Builds the scene cfg.kind names; throws InputError naming the field or file ("size_x_m",
// "file:line", ...).
std::unique_ptr<IScene> make_scene(const SceneConfig& cfg);

// The texture extent of a config (validated: throws InputError naming the field).
TextureExtent scene_texture(const SceneConfig& cfg);

}  // namespace vtsim
