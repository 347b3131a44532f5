#include <doctest/doctest.h>

#include <cmath>
#include <vector>

#include "core/error.h"
#include "sim/view/scene.h"
#include "sim/view/scene_plane.h"
#include "view_test_util.h"

using namespace vtsim;

namespace {

using LD = long double;
struct V3 {
  LD x, y, z;
};
LD dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// Independent long-double model of a yaw/pitch camera over the plane z = 0: the hit point from
// the ray, and the footprint from the inverse of the forward projection's Jacobian (ground (x, y)
// -> pixel), not from ray differentials as the renderer does.
struct Ref {
  bool hit = false;
  LD tu = 0, tv = 0;   // continuous level-0 texel coordinates of the hit
  LD lod = 0;          // isotropic
  LD lod_aniso = 0;    // anisotropic, max ratio 16
};

Ref reference(LD ox, LD oy, LD oz, LD yaw_deg, LD pitch_deg, LD vfov_deg, int W, int H, LD px, LD py, LD tpm,
              LD x0 = 0, LD y0 = 0, LD roll_deg = 0) {
  const LD pi = 3.141592653589793238462643383279502884L;
  const LD y = yaw_deg * pi / 180, p = pitch_deg * pi / 180, rl = roll_deg * pi / 180;
  const V3 F{std::cos(p) * std::cos(y), std::cos(p) * std::sin(y), std::sin(p)};
  const V3 L0{-std::sin(y), std::cos(y), 0};
  const V3 U0{-std::sin(p) * std::cos(y), -std::sin(p) * std::sin(y), std::cos(p)};
  // Roll about the view axis, right side down: left tilts towards up.
  const V3 L{std::cos(rl) * L0.x + std::sin(rl) * U0.x, std::cos(rl) * L0.y + std::sin(rl) * U0.y,
             std::cos(rl) * L0.z + std::sin(rl) * U0.z};
  const V3 U{std::cos(rl) * U0.x - std::sin(rl) * L0.x, std::cos(rl) * U0.y - std::sin(rl) * L0.y,
             std::cos(rl) * U0.z - std::sin(rl) * L0.z};
  const LD f = (H / 2.0L) / std::tan(vfov_deg * pi / 360);
  const LD cx = W / 2.0L, cy = H / 2.0L;
  const V3 d{f * F.x + (cx - px) * L.x + (cy - py) * U.x, f * F.y + (cx - px) * L.y + (cy - py) * U.y,
             f * F.z + (cx - px) * L.z + (cy - py) * U.z};
  Ref r;
  if (!(d.z * oz < 0)) return r;
  const LD t = -oz / d.z;
  r.hit = true;
  const LD X = ox + t * d.x, Y = oy + t * d.y;
  r.tu = (X - x0) * tpm;
  r.tv = (Y - y0) * tpm;
  const V3 q{X - ox, Y - oy, -oz};
  const LD a = dot(q, F), b = dot(q, L), c = dot(q, U);
  // px = cx − f·b/a, py = cy − f·c/a as functions of ground (X, Y).
  const LD j11 = -f * (L.x * a - b * F.x) / (a * a), j12 = -f * (L.y * a - b * F.y) / (a * a);
  const LD j21 = -f * (U.x * a - c * F.x) / (a * a), j22 = -f * (U.y * a - c * F.y) / (a * a);
  const LD det = j11 * j22 - j12 * j21;
  // Inverse: d(X, Y)/d(px) = (j22, −j21)/det, d(X, Y)/d(py) = (−j12, j11)/det.
  const LD lx = tpm * std::hypot(j22 / det, -j21 / det), ly = tpm * std::hypot(-j12 / det, j11 / det);
  r.lod = std::log2(std::max(lx, ly));
  const LD major = std::max(lx, ly), minor = std::min(lx, ly);
  r.lod_aniso = std::log2(major / std::min(major / minor, 16.0L));
  return r;
}

// The renderer's documented tolerance against the long-double reference: fast_log2 (2e-9) plus
// the float32 LOD (half an ulp: 2^-24·|lod| <= 2e-6 for |lod| < 32) plus double rounding.
constexpr double kLodTol = 4e-6;

bool level_ok(float lod, LD ref, int levels) {
  const int got = desired_level(lod, levels);
  const LD fl = std::floor(ref);
  if (std::fabs(static_cast<double>(ref - fl)) < kLodTol || std::fabs(static_cast<double>(ref - fl - 1)) < kLodTol)
    return std::abs(got - desired_level(static_cast<float>(std::round(ref)), levels)) <= 1;
  return got == desired_level(static_cast<float>(ref), levels);
}

bool texel_ok(std::int64_t got, LD ref) {
  const LD fl = std::floor(ref);
  if (ref - fl < 1e-6L || fl + 1 - ref < 1e-6L) return std::llabs(got - static_cast<std::int64_t>(std::round(ref))) <= 1;
  return got == static_cast<std::int64_t>(fl);
}

SceneConfig plane_cfg() { return SceneConfig{}; }  // 8192 m at 128 texels/m, origin (0, 0)

}  // namespace

TEST_CASE("plane: every sample matches the long-double closed form (heights / pitches / sizes / divisors)") {
  const auto scene = make_scene(plane_cfg());
  const int levels = mip_level_count(scene->texture());
  struct Case {
    double z, pitch;
    int w, h, div;
    double roll;
  };
  const Case cases[] = {{1.7, -10, 640, 480, 1, 0},   {1.7, -45, 1920, 1080, 8, 0}, {0.5, 0, 1921, 1081, 7, 0},
                        {30, -30, 1280, 720, 2, 0},   {300, -60, 3840, 2160, 16, 0}, {5000, -90, 800, 600, 3, 0},
                        {1.5, -1, 1920, 1080, 4, 0},  {100, 20, 1920, 1080, 8, 0},  {1.7, -20, 1280, 720, 4, 25},
                        {50, -70, 1920, 1080, 8, -130}};
  for (const Case& k : cases) {
    CAPTURE(k.z);
    CAPTURE(k.pitch);
    CAPTURE(k.div);
    CAPTURE(k.roll);
    const double yaw = 37.0, ox = 4000.25, oy = 3000.5;
    for (bool aniso : {false, true}) {
      ViewParams vp;
      vp.divisor = k.div;
      vp.anisotropic = aniso;
      ViewBuffer vb;
      scene->render(make_camera(pose_from_angles({ox, oy, k.z}, yaw, k.pitch, k.roll, 60), k.w, k.h), vp, vb);
      CHECK(vb.width == buffer_extent(k.w, k.div));
      CHECK(vb.height == buffer_extent(k.h, k.div));
      CHECK(vb.samples.size() + test::no_sample_total(vb.counters) ==
            static_cast<std::size_t>(vb.width) * static_cast<std::size_t>(vb.height));
      double worst = 0.0;
      int bad_levels = 0, bad_texels = 0, order_bad = 0;
      std::size_t hits = 0;
      std::uint32_t next_pixel = 0;
      for (const ViewSample& s : vb.samples) {
        order_bad += s.pixel < next_pixel;  // pixel order
        next_pixel = s.pixel + 1;
        const int bx = static_cast<int>(s.pixel % static_cast<std::uint32_t>(vb.width));
        const int by = static_cast<int>(s.pixel / static_cast<std::uint32_t>(vb.width));
        const Ref r = reference(ox, oy, k.z, yaw, k.pitch, 60, k.w, k.h, sample_pos(bx, k.div, k.w),
                                sample_pos(by, k.div, k.h), 128, 0, 0, k.roll);
        if (!r.hit) {
          ++order_bad;
          continue;
        }
        ++hits;
        const LD ref = aniso ? r.lod_aniso : r.lod;
        order_bad += !std::isfinite(s.lod);
        worst = std::max(worst, std::fabs(static_cast<double>(s.lod - ref)));
        bad_levels += !level_ok(s.lod, ref, levels);
        bad_texels += !texel_ok(s.u, r.tu) || !texel_ok(s.v, r.tv);
      }
      CHECK(hits > 0);
      CHECK(order_bad == 0);
      CHECK(worst <= kLodTol);
      CHECK(bad_levels == 0);
      CHECK(bad_texels == 0);
      // Every pixel the reference says hits the ground within the texture is a sample (no hit in
      // these views is nearer than 0.05 m or farther than 1e7 m, the default clip depths).
      std::size_t expected = 0;
      for (int by = 0; by < vb.height; ++by)
        for (int bx = 0; bx < vb.width; ++bx) {
          const Ref r = reference(ox, oy, k.z, yaw, k.pitch, 60, k.w, k.h, sample_pos(bx, k.div, k.w),
                                  sample_pos(by, k.div, k.h), 128, 0, 0, k.roll);
          if (r.hit && r.tu >= 0 && r.tv >= 0 && r.tu < (1 << 20) && r.tv < (1 << 20)) ++expected;
        }
      CHECK(vb.samples.size() == expected);
    }
  }
}

TEST_CASE("plane: divisor 8 reproduces divisor 1 exactly at the same full-resolution pixels") {
  const auto scene = make_scene(plane_cfg());
  for (double pitch : {-5.0, -35.0, -90.0}) {
    const Camera cam = make_camera(pose_from_angles({4096.3, 4100.7, 2.0}, 123.0, pitch, 3.0, 70), 1920, 1080);
    ViewParams p1, p8;
    p1.divisor = 1;
    p8.divisor = 8;
    ViewBuffer b1, b8;
    scene->render(cam, p1, b1);
    scene->render(cam, p8, b8);
    const std::vector<int> idx1 = test::sample_index(b1);
    const std::vector<int> idx8 = test::sample_index(b8);
    int mismatches = 0;
    for (int by = 0; by < b8.height; ++by)
      for (int bx = 0; bx < b8.width; ++bx) {
        const int fx = sample_pixel(bx, 8, 1920), fy = sample_pixel(by, 8, 1080);
        const int i8 = idx8[static_cast<std::size_t>(by * b8.width + bx)];
        const int i1 = idx1[static_cast<std::size_t>(fy * b1.width + fx)];
        if ((i8 < 0) != (i1 < 0)) {
          ++mismatches;
          continue;
        }
        if (i8 < 0) continue;
        const ViewSample& a = b8.samples[static_cast<std::size_t>(i8)];
        const ViewSample& b = b1.samples[static_cast<std::size_t>(i1)];
        mismatches += a.u != b.u || a.v != b.v || a.lod != b.lod;
      }
    CHECK(mismatches == 0);
    CHECK(b8.samples.size() > 0);
  }
}

TEST_CASE("plane: degenerate views give finite / documented results") {
  const auto scene = make_scene(plane_cfg());
  ViewParams vp;
  vp.divisor = 4;
  ViewBuffer vb;
  const std::size_t npix = static_cast<std::size_t>(buffer_extent(1920, 4)) * buffer_extent(1080, 4);

  SUBCASE("straight down: every pixel samples, LOD uniform near the centre") {
    scene->render(make_camera(pose_from_angles({4096, 4096, 10}, 0, -90), 1920, 1080), vp, vb);
    CHECK(vb.samples.size() == npix);
    int non_finite = 0;
    for (const ViewSample& s : vb.samples) non_finite += !std::isfinite(s.lod);
    CHECK(non_finite == 0);
    // At the image centre the footprint is tpm·h/f texels per pixel.
    const double f = 540.0 / std::tan(M_PI / 6.0);
    const ViewSample& c = vb.samples[static_cast<std::size_t>(vb.height / 2 * vb.width + vb.width / 2)];
    CHECK(c.lod == doctest::Approx(std::log2(128.0 * 10.0 / f)).epsilon(1e-3));
  }
  SUBCASE("straight up: all sky") {
    scene->render(make_camera(pose_from_angles({4096, 4096, 10}, 0, 90), 1920, 1080), vp, vb);
    CHECK(vb.samples.empty());
    CHECK(vb.counters.sky == npix);
  }
  SUBCASE("below the ground looking up: back faces, no samples") {
    scene->render(make_camera(pose_from_angles({4096, 4096, -3}, 0, 60), 1920, 1080), vp, vb);
    CHECK(vb.samples.empty());
    CHECK(vb.counters.backfacing > npix / 2);
    CHECK(vb.counters.backfacing + vb.counters.sky == npix);
  }
  SUBCASE("on the ground: every ground hit is at depth 0, clipped") {
    scene->render(make_camera(pose_from_angles({4096, 4096, 0}, 0, -20), 1920, 1080), vp, vb);
    CHECK(vb.samples.empty());
    CHECK(vb.counters.clipped + vb.counters.sky == npix);
    CHECK(vb.counters.clipped > 0);
  }
  SUBCASE("horizontal at the horizon: finite LODs, clamped by desired_level") {
    ViewParams tiny = vp;
    tiny.near_m = 1e-12;  // a camera 1 µm above the ground sees it from 1 µm on
    scene->render(make_camera(pose_from_angles({4096, 4096, 1e-6}, 0, 0), 1920, 1080), tiny, vb);
    CHECK(!vb.samples.empty());
    int bad = 0;
    for (const ViewSample& s : vb.samples) bad += !(std::isfinite(s.lod) && s.lod <= 64.0f && s.lod >= -64.0f);
    CHECK(bad == 0);
  }
  SUBCASE("far away from the texture: outside_texture, then sky") {
    scene->render(make_camera(pose_from_angles({-50000, 4096, 2}, 180, -10), 1920, 1080), vp, vb);
    CHECK(vb.samples.empty());
    CHECK(vb.counters.outside_texture > 0);
  }
}

TEST_CASE("plane: near and far clip at view depth / bias shifts every LOD") {
  const auto scene = make_scene(plane_cfg());
  const Camera cam = make_camera(pose_from_angles({4096, 4096, 1.7}, 0, -30), 640, 480);
  ViewParams vp;
  vp.divisor = 1;
  ViewBuffer all, cut, biased;
  scene->render(cam, vp, all);
  ViewParams clip = vp;
  clip.near_m = 3.0;
  clip.far_m = 10.0;
  scene->render(cam, clip, cut);
  CHECK(cut.samples.size() < all.samples.size());
  CHECK(cut.counters.clipped > 0);
  CHECK(cut.samples.size() + cut.counters.clipped == all.samples.size());
  int outside = 0;
  for (const ViewSample& s : cut.samples) {
    const glm::dvec3 d = cam.ray_dir(sample_pos(static_cast<int>(s.pixel % 640), 1, 640),
                                     sample_pos(static_cast<int>(s.pixel / 640), 1, 480));
    const double depth = -1.7 / d.z * cam.focal_px;
    outside += depth < 3.0 || depth > 10.0;
  }
  CHECK(outside == 0);
  ViewParams b = vp;
  b.lod_bias = -1.25f;
  scene->render(cam, b, biased);
  REQUIRE(biased.samples.size() == all.samples.size());
  double worst = 0.0;
  for (std::size_t i = 0; i < all.samples.size(); ++i)
    worst = std::max(worst, std::fabs(static_cast<double>(biased.samples[i].lod) -
                                      (static_cast<double>(all.samples[i].lod) - 1.25)));
  CHECK(worst <= 4e-6);
}

TEST_CASE("plane: planet-scale coordinates keep texels exact") {
  SceneConfig cfg;
  cfg.origin_x_m = 1e7;
  cfg.origin_y_m = -1e7;
  cfg.size_x_m = cfg.size_y_m = 0x1p34 / 128;  // 2^34 texels a side
  const auto scene = make_scene(cfg);
  const double ox = 1e7 + 123456.789, oy = -1e7 + 98765.4321;
  ViewParams vp;
  vp.divisor = 16;
  ViewBuffer vb;
  scene->render(make_camera(pose_from_angles({ox, oy, 3.0}, 10, -40), 1920, 1080), vp, vb);
  REQUIRE(!vb.samples.empty());
  int bad = 0;
  for (const ViewSample& s : vb.samples) {
    const int bx = static_cast<int>(s.pixel % static_cast<std::uint32_t>(vb.width));
    const int by = static_cast<int>(s.pixel / static_cast<std::uint32_t>(vb.width));
    const Ref r = reference(ox, oy, 3.0, 10, -40, 60, 1920, 1080, sample_pos(bx, 16, 1920), sample_pos(by, 16, 1080),
                            128, 1e7, -1e7);
    bad += !texel_ok(s.u, r.tu) || !texel_ok(s.v, r.tv) || std::fabs(static_cast<double>(s.lod - r.lod)) > kLodTol;
  }
  CHECK(bad == 0);
}

TEST_CASE("scene config rejects bad input") {
  SceneConfig c;
  c.texels_per_m = 0;
  CHECK_THROWS_AS(make_scene(c), InputError);
  c = SceneConfig{};
  c.size_x_m = std::nan("");
  CHECK_THROWS_AS(make_scene(c), InputError);
  c = SceneConfig{};
  c.size_y_m = 1e30;  // more than 2^34 texels
  CHECK_THROWS_AS(make_scene(c), InputError);
  c = SceneConfig{};
  c.kind = "mesh";  // no OBJ
  CHECK_THROWS_AS(make_scene(c), InputError);
  CHECK_THROWS_AS(find_scene("sphere"), InputError);
  CHECK(find_scene("town").name == "town");
  const auto s = make_scene(SceneConfig{});
  ViewParams bad;
  bad.divisor = -1;
  ViewBuffer vb;
  CHECK_THROWS_AS(s->render(make_camera(Pose{}, 64, 64), bad, vb), InputError);
}
