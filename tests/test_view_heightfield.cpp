#include <doctest/doctest.h>
#include <sys/stat.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <vector>

#include "core/error.h"
#include "core/image_io.h"
#include "sim/view/scene.h"
#include "sim/view/scene_heightfield.h"
#include "sim/view/scene_plane.h"
#include "test_util.h"
#include "view_test_util.h"

using namespace vtsim;

namespace {

using LD = long double;

Heightfield random_hf(int posts, double spacing, double amp, std::uint64_t seed) {
  Heightfield hf;
  hf.nx = hf.ny = posts;
  hf.spacing_m = spacing;
  std::uint64_t s = seed;
  for (int k = 0; k < posts * posts; ++k) {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    hf.z_m.push_back(static_cast<float>(amp * static_cast<double>(s >> 40) / static_cast<double>(1 << 24)));
  }
  return hf;
}

struct RefHit {
  bool hit = false;
  bool front = false;
  LD t = 0;
  LD x = 0, y = 0;
};

// Brute force over every triangle (Möller–Trumbore in long double), nearest hit with t >= t_near.
RefHit brute_force(const Heightfield& hf, const glm::dvec3& o, const glm::dvec3& d, LD t_near) {
  RefHit best;
  best.t = std::numeric_limits<LD>::infinity();
  const auto P = [&](int i, int j) {
    return std::array<LD, 3>{hf.x0_m + i * hf.spacing_m, hf.y0_m + j * hf.spacing_m,
                             static_cast<LD>(hf.z_m[static_cast<std::size_t>(j * hf.nx + i)])};
  };
  for (int j = 0; j + 1 < hf.ny; ++j)
    for (int i = 0; i + 1 < hf.nx; ++i) {
      const std::array<std::array<LD, 3>, 3> tris[2] = {{P(i, j), P(i + 1, j), P(i + 1, j + 1)},
                                                         {P(i, j), P(i + 1, j + 1), P(i, j + 1)}};
      for (const auto& tr : tris) {
        LD e1[3], e2[3], pv[3], tv[3], qv[3];
        for (int k = 0; k < 3; ++k) {
          e1[k] = tr[1][k] - tr[0][k];
          e2[k] = tr[2][k] - tr[0][k];
          tv[k] = static_cast<LD>(o[k]) - tr[0][k];
        }
        const LD D[3] = {d.x, d.y, d.z};
        pv[0] = D[1] * e2[2] - D[2] * e2[1];
        pv[1] = D[2] * e2[0] - D[0] * e2[2];
        pv[2] = D[0] * e2[1] - D[1] * e2[0];
        const LD det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
        if (det == 0) continue;
        const LD u = (tv[0] * pv[0] + tv[1] * pv[1] + tv[2] * pv[2]) / det;
        if (u < 0 || u > 1) continue;
        qv[0] = tv[1] * e1[2] - tv[2] * e1[1];
        qv[1] = tv[2] * e1[0] - tv[0] * e1[2];
        qv[2] = tv[0] * e1[1] - tv[1] * e1[0];
        const LD v = (D[0] * qv[0] + D[1] * qv[1] + D[2] * qv[2]) / det;
        if (v < 0 || u + v > 1) continue;
        const LD t = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) / det;
        if (t < t_near || t >= best.t) continue;
        best.hit = true;
        best.t = t;
        // Upward normal e1 × e2 (counter-clockwise seen from above): front when d·n < 0.
        const LD nz = e1[0] * e2[1] - e1[1] * e2[0];
        const LD nx = e1[1] * e2[2] - e1[2] * e2[1], ny = e1[2] * e2[0] - e1[0] * e2[2];
        best.front = D[0] * nx + D[1] * ny + D[2] * nz < 0;
        best.x = static_cast<LD>(o.x) + t * D[0];
        best.y = static_cast<LD>(o.y) + t * D[1];
      }
    }
  return best;
}

GroundTexture tex_for(double size_m) {
  return GroundTexture{0.0, 0.0, 128.0, {static_cast<std::int64_t>(size_m * 128), static_cast<std::int64_t>(size_m * 128)}};
}

}  // namespace

TEST_CASE("heightfield: quadtree ray cast agrees with brute force over all triangles") {
  const Heightfield hf = random_hf(17, 4.0, 12.0, 7);  // 64 m × 64 m of rough terrain
  const HeightfieldScene scene(hf, tex_for(64.0));
  struct View {
    glm::dvec3 pos;
    double yaw, pitch;
  };
  const View views[] = {{{-10, 30, 15}, 0, -20}, {{32, 32, 40}, 45, -89.9}, {{70, 70, 8}, 225, -10},
                        {{20, 10, 3}, 60, 5},     {{32, 32, -5}, 0, 40}};
  for (const View& w : views) {
    CAPTURE(w.yaw);
    const Camera cam = make_camera(pose_from_angles(w.pos, w.yaw, w.pitch, 0, 70), 120, 90);
    ViewParams vp;
    vp.divisor = 1;
    ViewBuffer vb;
    scene.render(cam, vp, vb);
    const std::vector<int> idx = test::sample_index(vb);
    int mismatch = 0, compared = 0, lod_bad = 0, smooth = 0, lod_checked = 0;
    const LD t_near = vp.near_m / cam.focal_px;
    for (int y = 0; y < 90; ++y)
      for (int x = 0; x < 120; ++x) {
        const glm::dvec3 d = cam.ray_dir(x + 0.5, y + 0.5);
        const RefHit r = brute_force(hf, cam.pos_m, d, t_near);
        const int i = idx[static_cast<std::size_t>(y * 120 + x)];
        const bool ref_sample = r.hit && r.front && r.x >= 0 && r.y >= 0 && r.x < 64 && r.y < 64;
        if (ref_sample != (i >= 0)) {
          ++mismatch;
          continue;
        }
        if (i < 0) continue;
        ++compared;
        const ViewSample& s = vb.samples[static_cast<std::size_t>(i)];
        mismatch += std::llabs(s.u - static_cast<std::int64_t>(std::floor(r.x * 128))) > 1 ||
                    std::llabs(s.v - static_cast<std::int64_t>(std::floor(r.y * 128))) > 1;
        // LOD against central differences of the brute-force hit point (step 1/64 pixel).
        if ((x + y) % 3 != 0) continue;  // the LOD check on a third of the pixels (brute force is slow)
        ++lod_checked;
        // Skipped where forward and backward differences disagree: the stencil crosses a crease
        // (triangle edge) or a silhouette, where the footprint is not differentiable.
        const LD h = 1.0L / 64;
        LD g[2][2];
        bool ok = true;
        for (int axis = 0; axis < 2; ++axis) {
          const double dxp = axis == 0 ? static_cast<double>(h) : 0.0, dyp = axis == 1 ? static_cast<double>(h) : 0.0;
          const RefHit a = brute_force(hf, cam.pos_m, cam.ray_dir(x + 0.5 + dxp, y + 0.5 + dyp), t_near);
          const RefHit b = brute_force(hf, cam.pos_m, cam.ray_dir(x + 0.5 - dxp, y + 0.5 - dyp), t_near);
          ok = ok && a.hit && b.hit;
          const LD fx = (a.x - r.x) / h, bxd = (r.x - b.x) / h, fy = (a.y - r.y) / h, byd = (r.y - b.y) / h;
          const LD scale = std::hypot(fx, fy) + std::hypot(bxd, byd);
          ok = ok && std::hypot(fx - bxd, fy - byd) <= 1e-3L * scale;
          g[axis][0] = (a.x - b.x) / (2 * h) * 128;
          g[axis][1] = (a.y - b.y) / (2 * h) * 128;
        }
        if (!ok) continue;
        ++smooth;
        const LD ref_lod = std::log2(std::max(std::hypot(g[0][0], g[0][1]), std::hypot(g[1][0], g[1][1])));
        lod_bad += std::fabs(static_cast<double>(static_cast<LD>(s.lod) - ref_lod)) > 1e-3;
      }
    if (w.pos.z < 0) {  // under the terrain: only back faces
      CHECK(compared == 0);
      CHECK(vb.counters.backfacing > 0);
    } else {
      CHECK(compared > 1000);
      CHECK(smooth > lod_checked * 4 / 5);  // the LOD comparison is not vacuous
    }
    CHECK(mismatch <= compared / 500);  // ties on shared edges and silhouettes only
    CHECK(lod_bad == 0);
    CHECK(vb.samples.size() + test::no_sample_total(vb.counters) == 120u * 90u);
  }
}

TEST_CASE("heightfield: a flat field renders what the plane renders") {
  Heightfield hf;
  hf.nx = hf.ny = 65;
  hf.spacing_m = 128.0;  // 8192 m: the default terrain
  hf.z_m.assign(65 * 65, 0.0f);
  const HeightfieldScene flat(hf, tex_for(8192.0));
  const auto plane = make_scene(SceneConfig{});
  const Camera cam = make_camera(pose_from_angles({4000, 4100, 1.7}, 20, -15), 1920, 1080);
  ViewParams vp;
  ViewBuffer a, b;
  flat.render(cam, vp, a);
  plane->render(cam, vp, b);
  REQUIRE(a.samples.size() == b.samples.size());
  int texel_diff = 0, pixel_diff = 0;
  double worst = 0.0;
  for (std::size_t i = 0; i < a.samples.size(); ++i) {
    if (a.samples[i].pixel != b.samples[i].pixel) {
      ++pixel_diff;
      continue;
    }
    texel_diff += a.samples[i].u != b.samples[i].u || a.samples[i].v != b.samples[i].v;
    worst = std::max(worst, std::fabs(static_cast<double>(a.samples[i].lod - b.samples[i].lod)));
  }
  CHECK(pixel_diff == 0);
  CHECK(texel_diff <= static_cast<int>(a.samples.size() / 1000));  // t = −oz/dz vs −oz·(1/dz): 1 ulp
  CHECK(worst < 1e-5);
}

TEST_CASE("heightfield: a ridge hides the ground behind it / degenerate views stay finite") {
  Heightfield hf;
  hf.nx = hf.ny = 65;
  hf.spacing_m = 4.0;  // 256 m
  hf.z_m.assign(65 * 65, 0.0f);
  for (int j = 0; j < 65; ++j) hf.z_m[static_cast<std::size_t>(j * 65 + 10)] = 50.0f;  // ridge at x = 40 m
  const HeightfieldScene scene(hf, tex_for(256.0));
  ViewParams vp;
  vp.divisor = 2;
  ViewBuffer vb;
  scene.render(make_camera(pose_from_angles({1, 128, 2}, 0, 0, 0, 90), 640, 480), vp, vb);
  REQUIRE(!vb.samples.empty());
  std::int64_t max_u = 0;
  for (const ViewSample& s : vb.samples) max_u = std::max(max_u, s.u);
  CHECK(max_u < 44 * 128);  // nothing beyond the ridge's far slope (x = 44 m) is seen

  SUBCASE("straight down and straight up") {
    scene.render(make_camera(pose_from_angles({100, 100, 30}, 0, -90), 320, 240), vp, vb);
    CHECK(vb.samples.size() == 160u * 120u);
    int bad = 0;
    for (const ViewSample& s : vb.samples) bad += !std::isfinite(s.lod);
    CHECK(bad == 0);
    scene.render(make_camera(pose_from_angles({100, 100, 30}, 0, 90), 320, 240), vp, vb);
    CHECK(vb.samples.empty());
    CHECK(vb.counters.sky == 160u * 120u);
  }
  SUBCASE("under the terrain: back faces") {
    scene.render(make_camera(pose_from_angles({100, 100, -1}, 0, 45), 320, 240), vp, vb);
    CHECK(vb.samples.empty());
    CHECK(vb.counters.backfacing > 0);
  }
  SUBCASE("near plane cuts the ridge away: the ground behind shows") {
    ViewParams near = vp;
    near.near_m = 45.0;
    scene.render(make_camera(pose_from_angles({1, 128, 2}, 0, 0, 0, 90), 640, 480), near, vb);
    std::int64_t far_u = 0;
    for (const ViewSample& s : vb.samples) far_u = std::max(far_u, s.u);
    CHECK(far_u > 44 * 128);
    CHECK(vb.counters.clipped > 0);
  }
}

TEST_CASE("heightfield: generated noise is deterministic / height_at matches the posts") {
  const Heightfield a = generate_heightfield(129, 8.0, 100.0, 5.0, 42, 0, 0);
  const Heightfield b = generate_heightfield(129, 8.0, 100.0, 5.0, 42, 0, 0);
  const Heightfield c = generate_heightfield(129, 8.0, 100.0, 5.0, 43, 0, 0);
  CHECK(a.z_m == b.z_m);
  CHECK(a.z_m != c.z_m);
  float lo = 1e9f, hi = -1e9f;
  for (float z : a.z_m) {
    lo = std::min(lo, z);
    hi = std::max(hi, z);
  }
  CHECK(lo >= -95.0f);
  CHECK(hi <= 105.0f);
  CHECK(hi - lo > 20.0f);
  const HeightfieldScene s(a, tex_for(1024.0));
  CHECK(s.height_at(8.0 * 3, 8.0 * 7) == static_cast<double>(a.z_m[7 * 129 + 3]));
  CHECK(std::isnan(s.height_at(-1.0, 5.0)));
  CHECK(std::isnan(s.height_at(5.0, 1024.5)));
  CHECK_THROWS_AS(generate_heightfield(1, 8.0, 1.0, 0.0, 1, 0, 0), InputError);
  CHECK_THROWS_AS(generate_heightfield(9000, 8.0, 1.0, 0.0, 1, 0, 0), InputError);
  CHECK_THROWS_AS(generate_heightfield(10, 0.0, 1.0, 0.0, 1, 0, 0), InputError);
  CHECK_THROWS_AS(generate_heightfield(10, 1.0, std::nan(""), 0.0, 1, 0, 0), InputError);
}

TEST_CASE("heightfield: images load as heights / bad files are rejected") {
  const std::string png = test::temp_path("hm.png");
  {
    std::vector<std::uint16_t> px(4 * 3);
    for (int k = 0; k < 12; ++k) px[static_cast<std::size_t>(k)] = static_cast<std::uint16_t>(k * 5000);
    REQUIRE(image_io::write_file(png, 4, 3, 1, image_io::PixelType::u16, px.data(), false).status ==
            image_io::WriteStatus::ok);
  }
  const Heightfield hf = load_heightfield(png, 2.0, 65.535, 10.0, 0.0, 0.0);
  CHECK(hf.nx == 4);
  CHECK(hf.ny == 3);
  CHECK(hf.z_m[5] == doctest::Approx(10.0 + 25.0));  // 25000/65535 · 65.535 m
  CHECK_THROWS_WITH_AS(load_heightfield(png, 2.0, 1.0, 0.0, 0.0, 0.0, 11), doctest::Contains("11-post limit"),
                       InputError);
  std::remove(png.c_str());

  // Cut short: an error naming the file (OpenImageIO leaks its message string here, which
  // scripts/lsan.supp suppresses for the ASan run), and a FIFO is refused, not waited on.
  const std::string big = test::temp_path("big.png"), cut = test::temp_path("cut.png"), fifo = test::temp_path("hm.fifo");
  {
    std::vector<std::uint16_t> px(64 * 64);
    for (std::size_t k = 0; k < px.size(); ++k) px[k] = static_cast<std::uint16_t>(k * 2654435761u >> 7);
    REQUIRE(image_io::write_file(big, 64, 64, 1, image_io::PixelType::u16, px.data(), false).status ==
            image_io::WriteStatus::ok);
    const std::string bytes = test::slurp(big);
    REQUIRE(bytes.size() > 200);
    std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  }
  CHECK_THROWS_WITH_AS(load_heightfield(cut, 1.0, 1.0, 0.0, 0.0, 0.0), doctest::Contains(cut.c_str()), InputError);
  // A cut TIFF reads "ok" with libtiff's error pending and the missing strips zero-filled: refused.
  const std::string cut_tif = test::temp_path("cut.tif");
  {
    std::vector<std::uint16_t> px(64 * 64);
    for (std::size_t k = 0; k < px.size(); ++k) px[k] = static_cast<std::uint16_t>(k * 2654435761u >> 7);
    REQUIRE(image_io::write_file(cut_tif, 64, 64, 1, image_io::PixelType::u16, px.data(), false).status ==
            image_io::WriteStatus::ok);
    test::cut_file(cut_tif, 0.5);
  }
  CHECK_THROWS_WITH_AS(load_heightfield(cut_tif, 1.0, 1.0, 0.0, 0.0, 0.0), doctest::Contains("is damaged"), InputError);
  std::remove(cut_tif.c_str());
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  CHECK_THROWS_WITH_AS(load_heightfield(fifo, 1.0, 1.0, 0.0, 0.0, 0.0), doctest::Contains("not a regular file"),
                       InputError);
  for (const std::string& f : {big, cut, fifo}) std::remove(f.c_str());

  const std::string tif = test::temp_path("nan.tif");
  {
    std::vector<float> px(9, 1.0f);
    px[5] = std::nanf("");
    REQUIRE(image_io::write_file(tif, 3, 3, 1, image_io::PixelType::f32, px.data(), false).status ==
            image_io::WriteStatus::ok);
  }
  try {
    load_heightfield(tif, 1.0, 1.0, 0.0, 0.0, 0.0);
    FAIL("expected InputError");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).find("row 1, column 2") != std::string::npos);
  }
  std::remove(tif.c_str());

  const std::string tiny = test::temp_path("tiny.png");
  {
    const std::uint8_t px = 7;
    REQUIRE(image_io::write_file(tiny, 1, 1, 1, image_io::PixelType::u8, &px, false).status ==
            image_io::WriteStatus::ok);
  }
  CHECK_THROWS_AS(load_heightfield(tiny, 1.0, 1.0, 0.0, 0.0, 0.0), InputError);
  std::remove(tiny.c_str());

  const std::string junk = test::temp_path("junk.png");
  std::ofstream(junk) << "not an image\n";
  CHECK_THROWS_AS(load_heightfield(junk, 1.0, 1.0, 0.0, 0.0, 0.0), InputError);
  std::remove(junk.c_str());
  CHECK_THROWS_AS(load_heightfield("/nonexistent/hm.png", 1.0, 1.0, 0.0, 0.0, 0.0), InputError);
  CHECK_THROWS_AS(load_heightfield(png, -1.0, 1.0, 0.0, 0.0, 0.0), InputError);

  Heightfield bad;
  bad.nx = 3;
  bad.ny = 3;
  bad.z_m.assign(8, 0.0f);  // wrong count
  CHECK_THROWS_AS(HeightfieldScene(bad, tex_for(8.0)), InputError);
  bad.z_m.assign(9, 0.0f);
  bad.z_m[4] = std::numeric_limits<float>::infinity();
  CHECK_THROWS_AS(HeightfieldScene(bad, tex_for(8.0)), InputError);
}
