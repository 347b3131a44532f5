#pragma once
// Heightfield terrain (docs/view.md): posts on a regular grid, each cell split into two triangles
// along its (i, j)–(i+1, j+1) diagonal, textured by planar projection of ground x, y. Rays are
// cast through a max-height quadtree ("maximum mipmap", Tevs et al. 2008): a node is skipped
// when the ray stays above its highest post over the node's footprint.
#include <cstdint>
#include <string>
#include <vector>

#include "sim/view/scene.h"
#include "sim/view/scene_plane.h"

namespace vtsim {

struct Heightfield {
  int nx = 0, ny = 0;            // posts along x and y (cells: nx−1 × ny−1)
  double spacing_m = 1.0;        // distance between neighbouring posts, metres
  double x0_m = 0.0, y0_m = 0.0; // world position of post (0, 0)
  std::vector<float> z_m;        // post heights, world metres, row-major: z_m[j·nx + i]
  std::vector<std::string> warnings;  // what the reader left out (IScene::load_warnings)
};

// Limits on untrusted heightmaps: at most 2^26 posts (256 MiB of float heights, a 8192² image).
inline constexpr std::int64_t kMaxHeightfieldPosts = std::int64_t{1} << 26;

// Reads the first channel of any image OpenImageIO reads (more channels: a line in
// Heightfield::warnings); z = z0 + scale·value (OIIO maps integer
// pixel types to [0, 1]). Image row j is post row j (world y grows with the image row). Throws
// InputError(path, ...) for unreadable files, damaged ones (the reader filled rows it could not
// decode), fewer than 2×2 or more than kMaxHeightfieldPosts posts, and (path:row r, column c) for
// a non-finite value.
// The size is checked from the image header before any pixel is decoded (max_posts: the limit),
// and so is the memory the read needs, OpenImageIO's buffers included (image_io::
// require_read_memory against max_bytes; 0 = usable_memory_bytes()).
Heightfield load_heightfield(const std::string& path, double spacing_m, double height_scale_m,
                             double z0_m, double x0_m, double y0_m,
                             std::int64_t max_posts = kMaxHeightfieldPosts, std::uint64_t max_bytes = 0);

// Deterministic value-noise fBm (6 octaves, lattice period 256 posts down to 8): hills of
// ±amplitude around z0. Same seed, same heights, bit for bit.
Heightfield generate_heightfield(int posts, double spacing_m, double amplitude_m, double z0_m,
                                 std::uint64_t seed, double x0_m, double y0_m);

// Render cost O(buffer pixels × nodes visited per ray) (≈ tens of nodes for ground-level views),
// no allocation during render; thread-safe (immutable after construction).
class HeightfieldScene final : public IScene {
 public:
  HeightfieldScene(Heightfield hf, const GroundTexture& tex);
  void surface_at(const Camera& cam, const ViewParams& params, double px, double py, SurfaceHit& hit) const override;
  TextureExtent texture() const override { return tex_.extent; }
  void render(const Camera& cam, const ViewParams& params, ViewBuffer& out) const override;

  // Surface height at world (x, y) (on the same triangles the renderer draws); NaN outside.
  double height_at(double x_m, double y_m) const;
  std::optional<double> ground_z(double x_m, double y_m) const override { return height_at(x_m, y_m); }
  const Heightfield& heightfield() const { return hf_; }
  std::vector<std::string> load_warnings() const override { return hf_.warnings; }

 private:
  struct Hit;
  Hit cast(const glm::dvec3& o, const glm::dvec3& d, double t_near) const;

  Heightfield hf_;
  GroundTexture tex_;
  int cells_x_ = 0, cells_y_ = 0;
  // Highest post over level-l node (i, j) = cells [i·2^l, (i+1)·2^l) × [j·2^l, (j+1)·2^l):
  // max_[level_off_[l] + j·level_w_[l] + i]; level 0 is one node per cell, the top one 1×1.
  static constexpr int kMaxLevels = 32;
  std::vector<float> max_;
  int levels_ = 0;
  std::size_t level_off_[kMaxLevels] = {};
  int level_w_[kMaxLevels] = {}, level_h_[kMaxLevels] = {};
};

}  // namespace vtsim
