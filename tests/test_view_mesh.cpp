#include <doctest/doctest.h>

#include <cstdio>
#include <fstream>
#include <string>

#include "core/error.h"
#include "sim/view/mesh.h"
#include "sim/view/scene.h"
#include "sim/view/scene_mesh.h"
#include "view_test_util.h"

using namespace vtsim;

namespace {

const TextureExtent kTex{1 << 20, 1 << 20};

// Expects parse_obj to throw an InputError whose message contains `where` and `what`.
void expect_error(const std::string& text, const std::string& where, const std::string& what) {
  CAPTURE(text);
  try {
    parse_obj(text, "t.obj");
    FAIL("expected InputError");
  } catch (const InputError& e) {
    const std::string msg = e.what();
    CAPTURE(msg);
    CHECK(msg.find(where) != std::string::npos);
    CHECK(msg.find(what) != std::string::npos);
  }
}

// The default terrain's ground (8192 m square) as one textured quad: u = x·128 like the plane.
const char* kGroundObj =
    "# ground\n"
    "v 0 0 0\nv 8192 0 0\nv 8192 8192 0\nv 0 8192 0\n"
    "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
    "f 1/1 2/2 3/3 4/4\n";

// Adds a quad (counter-clockwise seen from the front) with texel rectangle uv0..uv1.
void add_quad(Mesh& m, glm::dvec3 a, glm::dvec3 b, glm::dvec3 c, glm::dvec3 d, glm::dvec2 uv0, glm::dvec2 uv1) {
  const auto p = static_cast<std::uint32_t>(m.positions.size());
  const auto t = static_cast<std::int32_t>(m.uvs.size());
  for (const auto& v : {a, b, c, d}) m.positions.push_back(v);
  for (const auto& v : {uv0, glm::dvec2(uv1.x, uv0.y), uv1, glm::dvec2(uv0.x, uv1.y)}) m.uvs.push_back(v);
  m.tris.push_back(Mesh::Tri{{p, p + 1, p + 2}, {t, t + 1, t + 2}});
  m.tris.push_back(Mesh::Tri{{p, p + 2, p + 3}, {t, t + 2, t + 3}});
}

// Ground [0, 100]² in the lower-left quarter of the texture; a wall at x = 20 facing −x with its
// texels in the upper half (v >= 2^19).
Mesh ground_and_wall(double wall_half_width) {
  Mesh m;
  add_quad(m, {0, 0, 0}, {100, 0, 0}, {100, 100, 0}, {0, 100, 0}, {0, 0}, {0.25, 0.25});
  add_quad(m, {20, 50 + wall_half_width, 0}, {20, 50 - wall_half_width, 0}, {20, 50 - wall_half_width, 10},
           {20, 50 + wall_half_width, 10}, {0, 0.5}, {0.5, 0.75});
  return m;
}

}  // namespace

TEST_CASE("OBJ: v / vt / f forms / negative indices / polygons as fans / ignored statements") {
  ObjStats st;
  const Mesh m = parse_obj(
      "mtllib x.mtl\no thing\n"
      "v 0 0 0\nv 1 0 0 1.0\nv 1 1 0 0.5 0.5 0.5\nv 0 1 0\n"
      "vt 0 0\nvt 1 0 0\nvt 1 1\nvt 0.25\n"
      "vn 0 0 1\ns off\nusemtl m\n"
      "f 1/1/1 2/2/1 3/3/1 4/4/1   # quad -> 2 triangles\r\n"
      "f -4/-4 -3/-3 -2/-2\n"
      "f 1//1 2//1 3//1\n"
      "f 1 2 4\n"
      "l 1 2\n",
      "t.obj", &st);
  CHECK(m.positions.size() == 4);
  CHECK(m.uvs.size() == 4);
  CHECK(m.uvs[3] == glm::dvec2(0.25, 0.0));
  REQUIRE(m.tris.size() == 5);
  CHECK(m.tris[0].p[0] == 0);
  CHECK(m.tris[1].p[1] == 2);
  CHECK(m.tris[1].p[2] == 3);
  CHECK(m.tris[2].p[0] == 0);  // -4 of 4
  CHECK(m.tris[2].t[2] == 2);
  CHECK(m.tris[3].t[0] == -1);
  CHECK(m.tris[4].t[1] == -1);
  CHECK(st.faces == 4);
  CHECK(st.triangles == 5);
  CHECK(st.untextured_faces == 2);
  CHECK(st.ignored_statements == 6);  // mtllib o vn s usemtl l
  CHECK(st.lines == 18);
}

TEST_CASE("OBJ: degenerate triangles are skipped and counted") {
  ObjStats st;
  const Mesh m = parse_obj("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 1 4\nf 1 2 4\n", "t.obj", &st);
  CHECK(m.tris.size() == 1);
  CHECK(st.degenerate_skipped == 2);
  expect_error("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "t.obj", "no (non-degenerate) faces");
}

TEST_CASE("OBJ: malformed input names the file and line") {
  expect_error("v 0 0\n", "t.obj:1", "v needs 3 coordinates");
  expect_error("v 0 0 0 0 0 0 0 0\n", "t.obj:1", "v needs 3 coordinates");
  expect_error("v 0 0 x\n", "t.obj:1", "malformed vertex coordinate \"x\"");
  // Tokens are quoted as in the trace reader: cut at 40 bytes, control bytes (a NUL) escaped.
  expect_error("v 0 0 " + std::string(200, '7') + "x\n", "t.obj:1", "\"" + std::string(40, '7') + "...\"");
  expect_error(std::string("v 0 0 1\n") + "f 1/2" + std::string(1, '\0') + "3 1 1\n", "t.obj:2", "\\x00");
  expect_error("v 0 0 1e400\n", "t.obj:1", "not a finite number");
  expect_error("\n\nv nan 0 0\n", "t.obj:3", "not a finite number");
  expect_error("v inf 0 0\n", "t.obj:1", "not a finite number");
  expect_error("v 2e12 0 0\n", "t.obj:1", "within");
  expect_error("vt\n", "t.obj:1", "vt needs 1 to 3 numbers");
  expect_error("vt 0.5 nan\n", "t.obj:1", "not a finite number");
  expect_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "t.obj:4", "at least 3 corners");
  expect_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "t.obj:4", "out of range (3 defined so far)");
  expect_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "t.obj:4", "index 0");
  expect_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 1 2\n", "t.obj:4", "out of range");
  expect_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999999\n", "t.obj:4", "malformed vertex index");
  expect_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/a 2 3\n", "t.obj:4", "malformed texture coordinate index");
  expect_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n", "t.obj:5", "out of range (1 defined");
  expect_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2 3/1\n", "t.obj:5", "mixes corners");
  expect_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1/1 2 3\n", "t.obj:4", "malformed face corner");
  expect_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1/ 2/1/ 3/1/\n", "t.obj:5", "empty normal index");
  expect_error("v 0 0 0 \\\n1\n", "t.obj:1", "line continuation");
  expect_error("", "t.obj", "no (non-degenerate) faces");
  expect_error("# only a comment\n", "t.obj", "no (non-degenerate) faces");
}

TEST_CASE("OBJ: limits on gigantic inputs / unreadable files") {
  ObjLimits lim;
  lim.max_triangles = 3;
  CHECK_THROWS_WITH_AS(parse_obj("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 2 0\nv 1 2 0\nf 1 2 3 4 5 6\n", "t.obj",
                                 nullptr, lim),
                       doctest::Contains("t.obj:7: more than 3 triangles"), InputError);
  lim = ObjLimits{};
  lim.max_vertices = 2;
  CHECK_THROWS_WITH_AS(parse_obj("v 0 0 0\nv 1 0 0\nv 1 1 0\n", "t.obj", nullptr, lim),
                       doctest::Contains("t.obj:3: more than 2 vertices"), InputError);
  const std::string path = test::temp_path("big.obj");
  std::ofstream(path) << kGroundObj;
  lim = ObjLimits{};
  lim.max_bytes = 10;
  CHECK_THROWS_WITH_AS(load_obj(path, nullptr, lim), doctest::Contains("more than the limit"), InputError);
  ObjStats st;
  CHECK(load_obj(path, &st).tris.size() == 2);
  std::remove(path.c_str());
  CHECK_THROWS_AS(load_obj("/nonexistent/x.obj"), InputError);
  CHECK_THROWS_AS(load_obj("/"), InputError);  // a directory
}

TEST_CASE("mesh: a textured ground quad renders what the plane renders") {
  const MeshScene quad(parse_obj(kGroundObj, "ground.obj"), kTex);
  const auto plane = make_scene(SceneConfig{});
  for (double pitch : {-10.0, -60.0, -90.0}) {
    const Camera cam = make_camera(pose_from_angles({4000, 4100, 1.7}, 20, pitch), 1920, 1080);
    ViewParams vp;
    ViewBuffer a, b;
    quad.render(cam, vp, a);
    plane->render(cam, vp, b);
    REQUIRE(a.samples.size() == b.samples.size());
    int texel_diff = 0, pixel_diff = 0;
    double worst = 0.0;
    for (std::size_t i = 0; i < a.samples.size(); ++i) {
      if (a.samples[i].pixel != b.samples[i].pixel) {
      ++pixel_diff;
      continue;
    }
      texel_diff += std::llabs(a.samples[i].u - b.samples[i].u) + std::llabs(a.samples[i].v - b.samples[i].v) > 0;
      worst = std::max(worst, std::fabs(static_cast<double>(a.samples[i].lod - b.samples[i].lod)));
    }
    CHECK(pixel_diff == 0);
    CHECK(texel_diff <= static_cast<int>(a.samples.size() / 1000));
    CHECK(worst < 1e-5);
  }
}

TEST_CASE("mesh: divisor 8 reproduces divisor 1 exactly at the same full-resolution pixels") {
  SceneConfig cfg;
  cfg.kind = "town";
  const auto town = make_scene(cfg);
  const Camera cam = make_camera(pose_from_angles({10, 7, 1.7}, 35, -3), 1920, 1080);
  ViewParams p1, p8;
  p1.divisor = 1;
  p8.divisor = 8;
  ViewBuffer b1, b8;
  town->render(cam, p1, b1);
  town->render(cam, p8, b8);
  const std::vector<int> i1 = test::sample_index(b1), i8 = test::sample_index(b8);
  int mismatches = 0;
  for (int by = 0; by < b8.height; ++by)
    for (int bx = 0; bx < b8.width; ++bx) {
      const int a = i8[static_cast<std::size_t>(by * b8.width + bx)];
      const int b = i1[static_cast<std::size_t>(sample_pixel(by, 8, 1080) * 1920 + sample_pixel(bx, 8, 1920))];
      if ((a < 0) != (b < 0)) {
        ++mismatches;
        continue;
      }
      if (a < 0) continue;
      const ViewSample& s = b8.samples[static_cast<std::size_t>(a)];
      const ViewSample& t = b1.samples[static_cast<std::size_t>(b)];
      mismatches += s.u != t.u || s.v != t.v || s.lod != t.lod;
    }
  CHECK(mismatches == 0);
  CHECK(b8.samples.size() > 10000);
}

TEST_CASE("mesh: a wall hides the ground behind it / its back hides it too") {
  const MeshScene scene(ground_and_wall(1000.0), kTex);
  ViewParams vp;
  vp.divisor = 2;
  ViewBuffer vb;
  scene.render(make_camera(pose_from_angles({1, 50, 1.7}, 0, -5, 0, 90), 640, 480), vp, vb);
  std::size_t wall = 0, ground = 0;
  std::int64_t max_ground_u = 0;
  for (const ViewSample& s : vb.samples) {
    if (s.v >= (1 << 19)) {
      ++wall;
    } else {
      ++ground;
      max_ground_u = std::max(max_ground_u, s.u);
    }
  }
  CHECK(wall > 0);
  CHECK(ground > 0);
  CHECK(max_ground_u < 20 * (1 << 20) / 400 + 1);  // ground texels: u = x · 2^18 / 100 m; nothing past x = 20 m
  // The wall's texels run over its face: v from 2^19 (bottom) to 0.75·2^20 (top, 10 m).
  int off_wall = 0;
  for (const ViewSample& s : vb.samples) off_wall += s.v >= (1 << 19) && s.v >= 3 * (1 << 18);
  CHECK(off_wall == 0);

  // From behind (x = 30 looking −x) the wall is a back face: no samples on or through it.
  scene.render(make_camera(pose_from_angles({30, 50, 1.7}, 180, -5, 0, 90), 640, 480), vp, vb);
  CHECK(vb.counters.backfacing > 0);
  std::int64_t min_ground_u = 1 << 30;
  int wall_samples = 0;
  for (const ViewSample& s : vb.samples) {
    wall_samples += s.v >= (1 << 19);
    min_ground_u = std::min(min_ground_u, s.u);
  }
  CHECK(wall_samples == 0);
  CHECK(min_ground_u >= 20 * (1 << 20) / 400);  // nothing nearer than x = 20 m
}

TEST_CASE("mesh: coincident faces go to the triangle first in the mesh, culled or not") {
  // The ground [0, 100]² twice, as the same grid of 10 × 10 quads: once with texels in u < 2^18,
  // once in u >= 2^19. Every visible sample is an exact depth tie between the two copies (the
  // rule also decides samples on a silhouette edge, where a back face meets the front face
  // before it; there the hierarchy's order would otherwise show through).
  Mesh grid, other;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j) {
      const double x = 10.0 * i, y = 10.0 * j;
      add_quad(grid, {x, y, 0}, {x + 10, y, 0}, {x + 10, y + 10, 0}, {x, y + 10, 0}, {0, 0}, {0.25, 0.25});
      add_quad(other, {x, y, 0}, {x + 10, y, 0}, {x + 10, y + 10, 0}, {x, y + 10, 0}, {0.5, 0}, {0.75, 0.25});
    }
  const auto joined = [](const Mesh& first, const Mesh& second) {
    Mesh m = first;
    const auto p = static_cast<std::uint32_t>(m.positions.size());
    const auto t = static_cast<std::int32_t>(m.uvs.size());
    m.positions.insert(m.positions.end(), second.positions.begin(), second.positions.end());
    m.uvs.insert(m.uvs.end(), second.uvs.begin(), second.uvs.end());
    for (Mesh::Tri tri : second.tris) {
      for (int c = 0; c < 3; ++c) {
        tri.p[c] += p;
        tri.t[c] += t;
      }
      m.tris.push_back(tri);
    }
    return m;
  };
  const Camera cam = make_camera(pose_from_angles({50, 50, 40}, 30, -70), 640, 480);
  ViewParams vp;
  vp.divisor = 4;
  for (const bool grid_first : {true, false}) {
    CAPTURE(grid_first);
    MeshScene scene(grid_first ? joined(grid, other) : joined(other, grid), kTex);
    for (const bool culling : {true, false}) {
      CAPTURE(culling);
      scene.set_occlusion_culling(culling);
      ViewBuffer vb;
      scene.render(cam, vp, vb);
      REQUIRE(vb.samples.size() > 1000);
      std::size_t from_grid = 0;
      for (const ViewSample& s : vb.samples) from_grid += s.u < (1 << 18);
      CHECK(from_grid == (grid_first ? vb.samples.size() : 0));
    }
  }
}

TEST_CASE("mesh: a narrow wall occludes exactly the tiles behind it (frustum and occlusion)") {
  // With a 2 m-wide wall, ground behind it is hidden only within its shadow wedge.
  const MeshScene scene(ground_and_wall(1.0), kTex);
  ViewParams vp;
  vp.divisor = 1;
  ViewBuffer vb;
  const Camera cam = make_camera(pose_from_angles({1, 50, 1.7}, 0, -5, 0, 90), 320, 240);
  scene.render(cam, vp, vb);
  int in_shadow = 0, behind_visible = 0;
  for (const ViewSample& s : vb.samples) {
    if (s.v >= (1 << 19)) continue;
    const double x = static_cast<double>(s.u) * 100.0 / (1 << 18), y = static_cast<double>(s.v) * 100.0 / (1 << 18);
    if (x <= 20.1) continue;
    ++behind_visible;
    // The wedge seen from (1, 50): |y − 50| < (x − 1) / 19 · 1 m (the wall's half-width at x = 20).
    in_shadow += std::fabs(y - 50.0) < (x - 1.0) / 19.0 * 0.99 && x < 100.0;
  }
  CHECK(behind_visible > 100);
  CHECK(in_shadow == 0);

  // Everything behind the camera: culled, all sky.
  scene.render(make_camera(pose_from_angles({-10, 50, 1.7}, 180, 0), 320, 240), vp, vb);
  CHECK(vb.samples.empty());
  CHECK(vb.counters.sky == 320u * 240u);
}

TEST_CASE("mesh: camera inside a closed box sees only back faces / near plane cuts / untextured faces") {
  Mesh box;
  // Unit-ish box [0,4]³ with outward faces.
  const double a = 0, b = 4;
  add_quad(box, {b, a, a}, {b, b, a}, {b, b, b}, {b, a, b}, {0, 0}, {0.1, 0.1});
  add_quad(box, {a, b, a}, {a, a, a}, {a, a, b}, {a, b, b}, {0.2, 0}, {0.3, 0.1});
  add_quad(box, {b, b, a}, {a, b, a}, {a, b, b}, {b, b, b}, {0.4, 0}, {0.5, 0.1});
  add_quad(box, {a, a, a}, {b, a, a}, {b, a, b}, {a, a, b}, {0.6, 0}, {0.7, 0.1});
  add_quad(box, {a, a, b}, {b, a, b}, {b, b, b}, {a, b, b}, {0.8, 0}, {0.9, 0.1});
  add_quad(box, {a, b, a}, {b, b, a}, {b, a, a}, {a, a, a}, {0.0, 0.2}, {0.1, 0.3});
  const MeshScene scene(box, kTex);
  ViewParams vp;
  vp.divisor = 1;
  ViewBuffer vb;
  for (double yaw : {0.0, 90.0, 200.0})
    for (double pitch : {-90.0, 0.0, 45.0, 90.0}) {
      scene.render(make_camera(pose_from_angles({2, 2, 2}, yaw, pitch), 160, 120), vp, vb);
      CHECK(vb.samples.empty());
      CHECK(vb.counters.backfacing == 160u * 120u);
    }
  // Outside, the box is seen; with the near plane beyond the box, it is cut away: clipped, not sky.
  const Camera outside = make_camera(pose_from_angles({-1, 2, 2}, 0, 0, 0, 90), 160, 120);
  scene.render(outside, vp, vb);
  CHECK(vb.samples.size() > 1000);
  ViewParams cut = vp;
  cut.near_m = 20.0;
  scene.render(outside, cut, vb);
  CHECK(vb.samples.empty());
  CHECK(vb.counters.clipped > 1000);
  cut.near_m = 0.05;
  cut.far_m = 1.5;  // the box's front face is 1 m away, its inside back faces beyond 1.5 m
  scene.render(outside, cut, vb);
  CHECK(vb.samples.size() > 1000);
  // Faces without texture coordinates occlude but are not sampled.
  Mesh plain = box;
  for (auto& t : plain.tris) t.t[0] = t.t[1] = t.t[2] = -1;
  const MeshScene untextured(plain, kTex);
  untextured.render(outside, vp, vb);
  CHECK(vb.samples.empty());
  CHECK(vb.counters.untextured > 1000);
}

TEST_CASE("mesh: texture coordinates far outside the texture are outside-texture samples (no integer overflow)") {
  // A ground quad whose every corner has u = −7e9 or +9.3e9 (×2^20 texels: beyond ±2^52), as an
  // OBJ's `vt -7e9 0` gives: each sample is outside the texture. Below −2^52 texels the texel
  // index of such a lane overflowed in the batch resolve (UBSan: signed integer overflow),
  // though the value was never used.
  for (const double u : {-7e9, 9.3e9}) {
    Mesh m;
    add_quad(m, {0, 0, 0}, {100, 0, 0}, {100, 100, 0}, {0, 100, 0}, {u, 0}, {u, 0.25});
    const MeshScene scene(m, kTex);
    ViewParams vp;
    vp.divisor = 4;
    ViewBuffer vb;
    scene.render(make_camera(pose_from_angles({30, 30, 10}, 0, -89), 320, 240), vp, vb);
    CHECK(vb.samples.empty());
    CHECK(vb.counters.outside_texture == 80u * 60u);
    SpanBuffer sb;
    scene.render_spans(make_camera(pose_from_angles({30, 30, 10}, 0, -89), 320, 240), vp, sb);
    CHECK(sb.spans.empty());
    CHECK(sb.counters.outside_texture == 80u * 60u);
  }
}

TEST_CASE("mesh: construction rejects bad meshes") {
  Mesh m;
  CHECK_THROWS_AS(MeshScene(m, kTex), InputError);
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.tris.push_back(Mesh::Tri{{0, 1, 3}, {-1, -1, -1}});
  CHECK_THROWS_AS(MeshScene(m, kTex), InputError);
  m.tris[0] = Mesh::Tri{{0, 1, 2}, {0, 1, 2}};  // uv indices without uvs
  CHECK_THROWS_AS(MeshScene(m, kTex), InputError);
  m.tris[0] = Mesh::Tri{{0, 1, 1}, {-1, -1, -1}};  // zero area
  CHECK_THROWS_AS(MeshScene(m, kTex), InputError);
  m.tris[0] = Mesh::Tri{{0, 1, 2}, {-1, -1, -1}};
  CHECK_THROWS_AS(MeshScene(m, TextureExtent{0, 5}), InputError);
  CHECK_NOTHROW(MeshScene(m, kTex));
}
