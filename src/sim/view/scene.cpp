#include "sim/view/scene.h"

#include <cmath>
#include <stdexcept>

#include "core/error.h"
#include "core/tile_key.h"
#include "sim/view/scene_town.h"

namespace vtsim {

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

std::unique_ptr<IScene> make_plane_scene(const SceneConfig& cfg, TextureExtent extent);
std::unique_ptr<IScene> make_heightfield_scene(const SceneConfig& cfg, TextureExtent extent);
std::unique_ptr<IScene> make_file_mesh_scene(const SceneConfig& cfg, TextureExtent extent);
std::unique_ptr<IScene> make_town_scene(const SceneConfig& cfg, TextureExtent extent);
std::string town_where(double origin_x_m, double origin_y_m);

const Registry<SceneInfo>& scenes() {
  static const Registry<SceneInfo> table(
      "scene",
      {
          {"plane", "flat ground under the whole texture: the closed-form cases (clipmap bandwidth, LOD)", "", false,
           make_plane_scene, SceneFile::none, nullptr},
          {"heightfield", "terrain from a height image, or generated hills that occlude each other", "a height image (optional: noise without)",
           false, make_heightfield_scene, SceneFile::height_image, nullptr},
          {kTownScene, "a generated town: streets, buildings and walls, unique UVs, heavy occlusion (the VT case)", "", false,
           make_town_scene, SceneFile::none, town_where},
          {"mesh", "a scene file: OBJ whose UVs span the virtual texture (unique texturing, Yao 2011), or glTF/GLB, FBX, Collada, Quake 3 .pk3 ... through assimp, one region of the texture per material", "a mesh file (OBJ, glTF, FBX, Collada, .pk3, ...)", true,
           make_file_mesh_scene, SceneFile::mesh, nullptr},
      });
  return table;
}

const SceneInfo& find_scene(std::string_view name) {
  try {
    return scenes().at(name);
  } catch (const std::invalid_argument& e) {
    throw InputError("scene", e.what());
  }
}

std::unique_ptr<IScene> make_scene(const SceneConfig& cfg) {
  const SceneInfo& info = find_scene(cfg.kind);
  const TextureExtent ext = scene_texture(cfg);
  if (info.file_required && cfg.file.empty())
    throw InputError("scene.file", "the " + std::string(info.name) + " scene needs " + std::string(info.file));
  return info.make(cfg, ext);
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
