#include "sim/view/scene_heightfield.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "core/error.h"
#include "core/host_memory.h"
#include "core/image_io.h"
#include "core/tile_key.h"
#include "sim/view/render_util.h"

namespace vtsim {

namespace {

void check_grid_params(double spacing_m, double x0_m, double y0_m) {
  if (!(spacing_m > 0.0) || !std::isfinite(spacing_m))
    throw InputError("spacing_m", "post spacing must be finite and > 0");
  if (!std::isfinite(x0_m) || !std::isfinite(y0_m))
    throw InputError("origin", "heightfield origin must be finite");
}

// Value-noise lattice value in [-1, 1): a hash of (i, j, octave, seed).
double lattice(std::int64_t i, std::int64_t j, int octave, std::uint64_t seed) {
  std::uint64_t h = mix64(seed + 0x9e3779b97f4a7c15ULL * static_cast<std::uint64_t>(octave + 1));
  h = mix64(h ^ static_cast<std::uint64_t>(i));
  h = mix64(h ^ (static_cast<std::uint64_t>(j) * 0xd1b54a32d192ed03ULL));
  return static_cast<double>(h >> 11) * 0x1p-52 - 1.0;
}

}  // namespace

Heightfield load_heightfield(const std::string& path, double spacing_m, double height_scale_m,
                             double z0_m, double x0_m, double y0_m, std::int64_t max_posts,
                             std::uint64_t max_bytes) {
  max_posts = std::min(max_posts, kMaxHeightfieldPosts);
  check_grid_params(spacing_m, x0_m, y0_m);
  if (!std::isfinite(height_scale_m)) throw InputError("height_scale_m", "must be finite");
  if (!std::isfinite(z0_m)) throw InputError("z0_m", "must be finite");
  auto in = image_io::ImageReader::open_file(path, /*unassociated_alpha=*/false);
  if (!in) throw InputError(path, "cannot read as an image: " + in.error());
  const image_io::ImageSpec spec = in.spec();
  const std::int64_t w = spec.width, h = spec.height;
  if (spec.depth > 1) throw InputError(path, "volume images are not heightmaps");
  if (w < 2 || h < 2) throw InputError(path, "a heightmap needs at least 2×2 pixels");
  if (w * h > max_posts)
    throw InputError(path, std::to_string(w) + "×" + std::to_string(h) + " pixels is more than the " +
                               std::to_string(max_posts) + "-post limit");
  if (spec.channels < 1) throw InputError(path, "image has no channels");
  // The posts grow as rows are read: a header claiming more rows than the file holds fails at
  // the first missing chunk (4 MiB of rows), not after allocating them all.
  constexpr std::size_t kChunkBytes = std::size_t{4} << 20;
  const double chunk = image_io::chunk_read_bytes(spec, static_cast<std::size_t>(w) * 4, kChunkBytes);
  image_io::require_read_memory(path, spec, static_cast<double>(w * h) * 4.0 + chunk,
                                max_bytes != 0 ? max_bytes : usable_memory_bytes());
  std::vector<float> px;
  px.reserve(static_cast<std::size_t>(w * h));
  // Damage the reader papers over (a truncated JPEG or TIFF reads "ok" with rows of filler) is
  // refused: those rows would be terrain nobody made.
  switch (in.read_chunked<float>(1, kChunkBytes, image_io::OnDamage::stop, [&](int y0, int y1, const float* v) {
    px.insert(px.end(), v, v + static_cast<std::size_t>(y1 - y0) * static_cast<std::size_t>(w));
  })) {
    case image_io::ReadStatus::ok: break;
    case image_io::ReadStatus::failed: throw InputError(path, "cannot decode image: " + in.error());
    case image_io::ReadStatus::ok_with_error:
      throw InputError(path, "is damaged: " + in.error() + " (the first " +
                                 std::to_string(px.size() / static_cast<std::size_t>(w)) + " of " +
                                 std::to_string(h) + " rows read cleanly)");
  }
  Heightfield hf;
  hf.nx = static_cast<int>(w);
  hf.ny = static_cast<int>(h);
  hf.spacing_m = spacing_m;
  hf.x0_m = x0_m;
  hf.y0_m = y0_m;
  hf.z_m = std::move(px);  // converted in place below
  if (spec.channels > 1)
    hf.warnings.push_back(path + ": heights from the first of " + std::to_string(spec.channels) +
                          " channels; the other " + std::to_string(spec.channels - 1) + " ignored");
  for (std::int64_t j = 0; j < h; ++j)
    for (std::int64_t i = 0; i < w; ++i) {
      const float value = hf.z_m[static_cast<std::size_t>(j * w + i)];
      const double z = z0_m + height_scale_m * static_cast<double>(value);
      if (!std::isfinite(value) || !std::isfinite(z) || std::fabs(z) > 1e30)
        throw InputError(path + ": row " + std::to_string(j) + ", column " + std::to_string(i),
                         "height is not a finite number");
      hf.z_m[static_cast<std::size_t>(j * w + i)] = static_cast<float>(z);
    }
  return hf;
}

Heightfield generate_heightfield(int posts, double spacing_m, double amplitude_m, double z0_m,
                                 std::uint64_t seed, double x0_m, double y0_m) {
  check_grid_params(spacing_m, x0_m, y0_m);
  if (posts < 2 || static_cast<std::int64_t>(posts) * posts > kMaxHeightfieldPosts)
    throw InputError("noise_posts", "must be in [2, 8192]");
  if (!(amplitude_m >= 0.0) || !std::isfinite(amplitude_m) || amplitude_m > 1e6)
    throw InputError("noise_amplitude_m", "must be in [0, 1e6]");
  if (!std::isfinite(z0_m) || std::fabs(z0_m) > 1e12) throw InputError("z0_m", "must be finite");
  Heightfield hf;
  hf.nx = hf.ny = posts;
  hf.spacing_m = spacing_m;
  hf.x0_m = x0_m;
  hf.y0_m = y0_m;
  hf.z_m.resize(static_cast<std::size_t>(posts) * static_cast<std::size_t>(posts));
  constexpr int kOctaves = 6, kBasePeriod = 256;  // periods 256, 128, ..., 8 posts
  for (int j = 0; j < posts; ++j)
    for (int i = 0; i < posts; ++i) {
      double sum = 0.0, amp = 1.0, norm = 0.0;
      for (int k = 0; k < kOctaves; ++k) {
        const int period = kBasePeriod >> k;
        const std::int64_t li = i / period, lj = j / period;
        const double fx = static_cast<double>(i % period) / period;
        const double fy = static_cast<double>(j % period) / period;
        const double sx = fx * fx * (3.0 - 2.0 * fx), sy = fy * fy * (3.0 - 2.0 * fy);
        const double a = lattice(li, lj, k, seed), b = lattice(li + 1, lj, k, seed);
        const double c = lattice(li, lj + 1, k, seed), d = lattice(li + 1, lj + 1, k, seed);
        sum += amp * ((a + (b - a) * sx) * (1.0 - sy) + (c + (d - c) * sx) * sy);
        norm += amp;
        amp *= 0.5;
      }
      hf.z_m[static_cast<std::size_t>(j) * static_cast<std::size_t>(posts) + static_cast<std::size_t>(i)] =
          static_cast<float>(z0_m + amplitude_m * sum / norm);
    }
  return hf;
}

HeightfieldScene::HeightfieldScene(Heightfield hf, const GroundTexture& tex) : hf_(std::move(hf)), tex_(tex) {
  check_grid_params(hf_.spacing_m, hf_.x0_m, hf_.y0_m);
  if (hf_.nx < 2 || hf_.ny < 2 ||
      static_cast<std::int64_t>(hf_.nx) * hf_.ny > kMaxHeightfieldPosts ||
      hf_.z_m.size() != static_cast<std::size_t>(hf_.nx) * static_cast<std::size_t>(hf_.ny))
    throw InputError("heightfield", "needs nx·ny heights with 2 <= nx, ny and nx·ny <= 2^26");
  for (float z : hf_.z_m)
    if (!std::isfinite(z)) throw InputError("heightfield", "height is not finite");
  cells_x_ = hf_.nx - 1;
  cells_y_ = hf_.ny - 1;
  // Level 0: one node per cell, its highest corner; level l+1 halves with ceil up to 1×1.
  int w = cells_x_, h = cells_y_;
  const auto post = [&](int i, int j) {
    return hf_.z_m[static_cast<std::size_t>(j) * static_cast<std::size_t>(hf_.nx) + static_cast<std::size_t>(i)];
  };
  while (true) {
    level_off_[levels_] = max_.size();
    level_w_[levels_] = w;
    level_h_[levels_] = h;
    max_.resize(max_.size() + static_cast<std::size_t>(w) * static_cast<std::size_t>(h),
                -std::numeric_limits<float>::infinity());
    float* m = max_.data() + level_off_[levels_];
    if (levels_ == 0) {
      for (int j = 0; j < h; ++j)
        for (int i = 0; i < w; ++i)
          m[static_cast<std::size_t>(j) * static_cast<std::size_t>(w) + static_cast<std::size_t>(i)] =
              std::max(std::max(post(i, j), post(i + 1, j)), std::max(post(i, j + 1), post(i + 1, j + 1)));
    } else {
      const float* prev = max_.data() + level_off_[levels_ - 1];
      const int pw = level_w_[levels_ - 1], ph = level_h_[levels_ - 1];
      for (int j = 0; j < ph; ++j)
        for (int i = 0; i < pw; ++i) {
          float& v = m[static_cast<std::size_t>(j / 2) * static_cast<std::size_t>(w) + static_cast<std::size_t>(i / 2)];
          v = std::max(v, prev[static_cast<std::size_t>(j) * static_cast<std::size_t>(pw) + static_cast<std::size_t>(i)]);
        }
    }
    ++levels_;
    if (w == 1 && h == 1) break;
    w = (w + 1) / 2;
    h = (h + 1) / 2;
  }
}

double HeightfieldScene::height_at(double x_m, double y_m) const {
  const double X = (x_m - hf_.x0_m) / hf_.spacing_m, Y = (y_m - hf_.y0_m) / hf_.spacing_m;
  if (!(X >= 0.0 && X <= cells_x_ && Y >= 0.0 && Y <= cells_y_))
    return std::numeric_limits<double>::quiet_NaN();
  const int i = std::min(static_cast<int>(X), cells_x_ - 1), j = std::min(static_cast<int>(Y), cells_y_ - 1);
  const double fx = X - i, fy = Y - j;
  const auto post = [&](int a, int b) {
    return static_cast<double>(hf_.z_m[static_cast<std::size_t>(b) * hf_.nx + a]);
  };
  const double h00 = post(i, j), h10 = post(i + 1, j), h01 = post(i, j + 1), h11 = post(i + 1, j + 1);
  if (fx >= fy) return h00 + (h10 - h00) * fx + (h11 - h10) * fy;  // triangle (00, 10, 11)
  return h00 + (h11 - h01) * fx + (h01 - h00) * fy;                // triangle (00, 11, 01)
}

struct HeightfieldScene::Hit {
  double t = 0.0;          // ray parameter of the nearest hit with t >= t_near
  double b = 0.0, c = 0.0; // its triangle: z = a + b·fx + c·fy in cell units
  bool found = false;
  bool clipped = false;    // some hit lay nearer than t_near (the near plane cut it away)
};

// Maximum-mipmap ray march (Tevs, Ihrke, Seidel 2008): the ray walks the quadtree's nodes in the
// order it crosses them, like a 2-D DDA at a variable level. A node whose highest post lies below
// the ray over the ray's stretch inside it is stepped over whole (and the walk climbs a level when
// it leaves the parent); otherwise the walk descends into the child the ray is in, down to the
// cells, whose two triangles are intersected. Node indices advance by integer steps, so the walk
// terminates whatever the rounding; the first cell hit at or beyond t_near is the nearest hit.
HeightfieldScene::Hit HeightfieldScene::cast(const glm::dvec3& o, const glm::dvec3& d, double t_near) const {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  constexpr double kEps = 1e-9;  // cell-unit tolerance: a ray through a shared edge hits one side
  const double s = hf_.spacing_m;
  const double X = (o.x - hf_.x0_m) / s, Y = (o.y - hf_.y0_m) / s, oz = o.z;
  const double dX = d.x / s, dY = d.y / s, dz = d.z;
  const double ix = dX != 0.0 ? 1.0 / dX : 0.0, iy = dY != 0.0 ? 1.0 / dY : 0.0;
  Hit hit;
  // Where the ray (t >= 0) is over the grid's footprint [0, cells_x] × [0, cells_y].
  double t = 0.0, t_end = kInf;
  const auto slab = [&](double p, double id, double dp, double hi) {
    if (dp == 0.0) {
      if (p < 0.0 || p > hi) t = kInf;
      return;
    }
    double a = (0.0 - p) * id, b = (hi - p) * id;
    if (a > b) std::swap(a, b);
    t = std::max(t, a);
    t_end = std::min(t_end, b);
  };
  slab(X, ix, dX, cells_x_);
  slab(Y, iy, dY, cells_y_);
  if (!(t <= t_end)) return hit;
  const int sx = dX > 0.0 ? 1 : -1, sy = dY > 0.0 ? 1 : -1;
  const int top = levels_ - 1;
  const float* maxp = max_.data();
  int l = top, ni = 0, nj = 0;
  const float* posts = hf_.z_m.data();
  const int nx = hf_.nx;
  while (true) {
    const int lo_x = ni << l, hi_x = std::min((ni + 1) << l, cells_x_);
    const int lo_y = nj << l, hi_y = std::min((nj + 1) << l, cells_y_);
    const double tx = dX > 0.0 ? (hi_x - X) * ix : dX < 0.0 ? (lo_x - X) * ix : kInf;
    const double ty = dY > 0.0 ? (hi_y - Y) * iy : dY < 0.0 ? (lo_y - Y) * iy : kInf;
    const double te = std::max(t, std::min(tx, ty));
    const double zmin = dz >= 0.0 ? oz + t * dz : oz + te * dz;
    const float node_max = maxp[level_off_[l] + static_cast<std::size_t>(nj) * static_cast<std::size_t>(level_w_[l]) +
                                static_cast<std::size_t>(ni)];
    if (zmin <= static_cast<double>(node_max)) {
      if (l > 0) {  // descend into the child the ray is in at t
        const int half = 1 << (l - 1);
        const double px = X + t * dX, py = Y + t * dY;
        const int cw = level_w_[l - 1], ch = level_h_[l - 1];
        ni = std::min(2 * ni + (px >= lo_x + half ? 1 : 0), cw - 1);
        nj = std::min(2 * nj + (py >= lo_y + half ? 1 : 0), ch - 1);
        --l;
        continue;
      }
      // A cell: its two triangles, z = h00 + b·fx + c·fy in cell-local coordinates.
      const std::size_t base = static_cast<std::size_t>(nj) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(ni);
      const double h00 = posts[base], h10 = posts[base + 1], h01 = posts[base + static_cast<std::size_t>(nx)],
                   h11 = posts[base + static_cast<std::size_t>(nx) + 1];
      const double X0 = X - ni, Y0 = Y - nj;
      const double tri[2][2] = {{h10 - h00, h11 - h10}, {h11 - h01, h01 - h00}};
      double best = kInf;
      int best_k = -1;
      for (int k = 0; k < 2; ++k) {
        const double b = tri[k][0], c = tri[k][1];
        const double den = dz - b * dX - c * dY;  // d·n with n = (−b/s, −c/s, 1)
        if (den == 0.0) continue;
        const double th = (h00 + b * X0 + c * Y0 - oz) / den;
        if (!(th > 0.0)) continue;
        const double fx = X0 + th * dX, fy = Y0 + th * dY;
        if (!(fx >= -kEps && fx <= 1.0 + kEps && fy >= -kEps && fy <= 1.0 + kEps)) continue;
        if (k == 0 ? fx - fy < -kEps : fy - fx < -kEps) continue;
        if (th < t_near) {
          hit.clipped = true;
          continue;
        }
        if (th < best) {
          best = th;
          best_k = k;
        }
      }
      if (best_k >= 0) {
        hit.found = true;
        hit.t = best;
        hit.b = tri[best_k][0];
        hit.c = tri[best_k][1];
        return hit;
      }
    }
    // Step over the node to its neighbour along the ray; climb when leaving the parent.
    if (te == kInf || te > t_end) return hit;
    t = te;
    const int oi = ni, oj = nj;
    if (tx <= ty) ni += sx;
    if (ty <= tx) nj += sy;
    if (ni < 0 || nj < 0 || ni >= level_w_[l] || nj >= level_h_[l])
      return hit;
    if (l < top && ((ni >> 1) != (oi >> 1) || (nj >> 1) != (oj >> 1))) {
      ++l;
      ni >>= 1;
      nj >>= 1;
    }
  }
}

void HeightfieldScene::render(const Camera& cam, const ViewParams& p, ViewBuffer& out) const {
  detail::begin_frame(cam, p, out);
  const LodRule rule = detail::lod_rule(p);
  const double f = cam.focal_px;
  const double t_near = p.near_m / f, t_far = p.far_m / f;
  const double tpm = tex_.texels_per_m, s = hf_.spacing_m;
  const glm::dvec3 gu(tpm, 0.0, 0.0), gv(0.0, tpm, 0.0);
  const glm::dvec3 ddx = -cam.left, ddy = -cam.up;
  const double ox = cam.pos_m.x - tex_.x0_m, oy = cam.pos_m.y - tex_.y0_m;
  const int div = p.divisor, bw = out.width, bh = out.height;
  ViewCounters c;
  for (int by = 0; by < bh; ++by) {
    const double py = sample_pos(by, div, cam.height);
    for (int bx = 0; bx < bw; ++bx) {
      const glm::dvec3 d = cam.ray_dir(sample_pos(bx, div, cam.width), py);
      const Hit h = cast(cam.pos_m, d, t_near);
      if (!h.found) {
        if (h.clipped) ++c.clipped;
        else ++c.sky;
        continue;
      }
      if (h.t > t_far) {
        ++c.clipped;
        continue;
      }
      const glm::dvec3 n(-h.b / s, -h.c / s, 1.0);
      if (!(glm::dot(d, n) < 0.0)) {
        ++c.backfacing;
        continue;
      }
      std::int64_t u, v;
      if (!detail::texel_index((ox + h.t * d.x) * tpm, tex_.extent.width, u) ||
          !detail::texel_index((oy + h.t * d.y) * tpm, tex_.extent.height, v)) {
        ++c.outside_texture;
        continue;
      }
      const double lod = plane_footprint_lod(d, h.t, n, ddx, ddy, gu, gv, rule);
      out.samples.push_back(ViewSample{u, v, static_cast<float>(lod), static_cast<std::uint32_t>(by * bw + bx)});
    }
  }
  out.counters = c;
}

// The table's "heightfield" (scene.cpp): cfg.file's image, or generated noise without one.
std::unique_ptr<IScene> make_heightfield_scene(const SceneConfig& cfg, TextureExtent extent) {
  Heightfield hf = cfg.file.empty() ? generate_heightfield(cfg.noise_posts, cfg.spacing_m, cfg.noise_amplitude_m, cfg.z0_m,
                                                          cfg.seed, cfg.origin_x_m, cfg.origin_y_m)
                                    : load_heightfield(cfg.file, cfg.spacing_m, cfg.height_scale_m, cfg.z0_m,
                                                       cfg.origin_x_m, cfg.origin_y_m);
  return std::make_unique<HeightfieldScene>(std::move(hf), GroundTexture{cfg.origin_x_m, cfg.origin_y_m, cfg.texels_per_m, extent});
}

}  // namespace vtsim

namespace vtsim {

// render()'s classification and texel map for one ray (gpu_model.h).
void HeightfieldScene::surface_at(const Camera& cam, const ViewParams& p, double px, double py, SurfaceHit& out) const {
  out = SurfaceHit{};
  const double f = cam.focal_px;
  const glm::dvec3 d = cam.ray_dir(px, py);
  const Hit h = cast(cam.pos_m, d, p.near_m / f);
  if (!h.found) {
    out.kind = h.clipped ? SurfaceHit::clipped : SurfaceHit::none;
    return;
  }
  if (h.t > p.far_m / f) {
    out.kind = SurfaceHit::clipped;
    return;
  }
  const double s = hf_.spacing_m, tpm = tex_.texels_per_m;
  out.n = glm::dvec3(-h.b / s, -h.c / s, 1.0);
  if (!(glm::dot(d, out.n) < 0.0)) {
    out.kind = SurfaceHit::backfacing;
    return;
  }
  out.p = cam.pos_m + h.t * d;
  out.tu = (cam.pos_m.x - tex_.x0_m + h.t * d.x) * tpm;
  out.tv = (cam.pos_m.y - tex_.y0_m + h.t * d.y) * tpm;
  out.gu = glm::dvec3(tpm, 0.0, 0.0);
  out.gv = glm::dvec3(0.0, tpm, 0.0);
  std::int64_t u = 0, v = 0;
  out.kind = detail::texel_index(out.tu, tex_.extent.width, u) && detail::texel_index(out.tv, tex_.extent.height, v)
                 ? SurfaceHit::sample
                 : SurfaceHit::outside_texture;
}

}  // namespace vtsim
