#include "sim/view/scene.h"

#include <cmath>
#include <stdexcept>

#include "core/error.h"
#include "core/tile_key.h"
#include "sim/view/scene_heightfield.h"
#include "sim/view/scene_mesh.h"
#include "sim/view/scene_plane.h"
#include "sim/view/scene_town.h"

namespace vtsim {

SceneKind parse_scene_kind(const std::string& s) {
  if (s == "plane") return SceneKind::plane;
  if (s == "heightfield") return SceneKind::heightfield;
  if (s == "mesh") return SceneKind::mesh;
  if (s == "town") return SceneKind::town;
  throw InputError("scene", "unknown scene '" + s + "' (plane | heightfield | mesh | town)");
}

const char* scene_kind_name(SceneKind k) {
  switch (k) {
    case SceneKind::plane: return "plane";
    case SceneKind::heightfield: return "heightfield";
    case SceneKind::mesh: return "mesh";
    case SceneKind::town: return "town";
  }
  return "?";
}

TextureExtent scene_texture(const SceneConfig& cfg) {
  // Largest side: 2^27 tiles of 128 texels (TileKey's coordinate range) = 2^34 texels.
  constexpr double kMaxSide = 0x1p34;
  if (!(cfg.texels_per_m > 0.0) || !std::isfinite(cfg.texels_per_m))
    throw InputError("texels_per_m", "must be finite and > 0");
  if (!(cfg.size_x_m > 0.0) || !std::isfinite(cfg.size_x_m)) throw InputError("size_x_m", "must be finite and > 0");
  if (!(cfg.size_y_m > 0.0) || !std::isfinite(cfg.size_y_m)) throw InputError("size_y_m", "must be finite and > 0");
  if (!std::isfinite(cfg.origin_x_m)) throw InputError("origin_x_m", "must be finite");
  if (!std::isfinite(cfg.origin_y_m)) throw InputError("origin_y_m", "must be finite");
  const double w = std::round(cfg.size_x_m * cfg.texels_per_m), h = std::round(cfg.size_y_m * cfg.texels_per_m);
  if (!(w >= 1.0 && w <= kMaxSide)) throw InputError("size_x_m", "texture width must be 1 .. 2^34 texels");
  if (!(h >= 1.0 && h <= kMaxSide)) throw InputError("size_y_m", "texture height must be 1 .. 2^34 texels");
  return TextureExtent{static_cast<std::int64_t>(w), static_cast<std::int64_t>(h)};
}

std::unique_ptr<IScene> make_scene(const SceneConfig& cfg) {
  const TextureExtent ext = scene_texture(cfg);
  const GroundTexture ground{cfg.origin_x_m, cfg.origin_y_m, cfg.texels_per_m, ext};
  switch (cfg.kind) {
    case SceneKind::plane:
      if (!std::isfinite(cfg.plane_z_m)) throw InputError("plane_z_m", "must be finite");
      return std::make_unique<PlaneScene>(ground, cfg.plane_z_m);
    case SceneKind::heightfield: {
      Heightfield hf = cfg.heightmap_path.empty()
                           ? generate_heightfield(cfg.noise_posts, cfg.spacing_m, cfg.noise_amplitude_m, cfg.z0_m,
                                                  cfg.seed, cfg.origin_x_m, cfg.origin_y_m)
                           : load_heightfield(cfg.heightmap_path, cfg.spacing_m, cfg.height_scale_m, cfg.z0_m,
                                              cfg.origin_x_m, cfg.origin_y_m);
      return std::make_unique<HeightfieldScene>(std::move(hf), ground);
    }
    case SceneKind::mesh:
      if (cfg.obj_path.empty()) throw InputError("obj_path", "the mesh scene needs an OBJ file");
      return std::make_unique<MeshScene>(load_obj(cfg.obj_path), ext);
    case SceneKind::town:
      return std::make_unique<MeshScene>(generate_town(cfg), ext);
  }
  throw InputError("scene", "unknown scene kind");
}

// IScene's defaults: a scene without a span renderer renders per sample and derives the spans.
void IScene::render_spans(const Camera& cam, const ViewParams& params, SpanBuffer& out) const {
  check_block_shift(out.block_shift);
  render(cam, params, out.view);
  out.width = out.view.width;
  out.height = out.view.height;
  out.divisor = out.view.divisor;
  out.counters = out.view.counters;
  out.samples = out.view.samples.size();
  out.has_samples = true;
  out.scene = this;
  out.cam = cam;
  out.params = params;
  out.levels = mip_level_count(texture());
  spans_from_samples(out.view, out.levels, out.block_shift, out.spans);
}

void IScene::render_pixels(const SpanBuffer&, std::uint32_t, std::uint32_t, std::vector<ViewSample>&) const {
  throw std::logic_error("render_pixels: this scene keeps its samples (render_spans sets has_samples)");
}

}  // namespace vtsim
