#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "core/error.h"
#include "sim/view/mesh.h"
#include "sim/view/mesh_import.h"
#include "sim/view/scene.h"
#include "sim/view/scene_mesh.h"

using namespace vtsim;

namespace {

// One glTF primitive: float positions (xyz), UVs (uv, empty = none), indices, material.
struct MiPrim {
  std::vector<float> pos;
  std::vector<float> uv;
  std::vector<std::uint32_t> idx;
  int material = 0;
};

std::string mi_base64(const std::string& in) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const std::uint32_t n = (std::uint32_t{static_cast<unsigned char>(in[i])} << 16) |
                            (std::uint32_t{static_cast<unsigned char>(in[i + 1])} << 8) | static_cast<unsigned char>(in[i + 2]);
    for (int s = 18; s >= 0; s -= 6) out += k[(n >> s) & 63];
  }
  if (i + 1 == in.size()) {
    const std::uint32_t n = std::uint32_t{static_cast<unsigned char>(in[i])} << 16;
    out += k[(n >> 18) & 63];
    out += k[(n >> 12) & 63];
    out += "==";
  } else if (i + 2 == in.size()) {
    const std::uint32_t n = (std::uint32_t{static_cast<unsigned char>(in[i])} << 16) |
                            (std::uint32_t{static_cast<unsigned char>(in[i + 1])} << 8);
    out += k[(n >> 18) & 63];
    out += k[(n >> 12) & 63];
    out += k[(n >> 6) & 63];
    out += '=';
  }
  return out;
}

// A .gltf with one embedded buffer: one mesh per primitive, one node per mesh carrying `node_trs`
// (JSON members such as "translation":[...], or empty), `materials` materials.
// With glb_bin: the buffer goes there (a GLB's BIN chunk), not into a data URI.
std::string mi_gltf(const std::vector<MiPrim>& prims, int materials, const std::string& node_trs = "",
                    std::string* glb_bin = nullptr) {
  std::string bin, views, accessors, meshes, nodes, scene_nodes;
  int view = 0;
  const auto add_view = [&](const void* data, std::size_t bytes) {
    const std::size_t off = bin.size();
    bin.append(static_cast<const char*>(data), bytes);
    while (bin.size() % 4) bin += '\0';
    views += std::string(view ? "," : "") + "{\"buffer\":0,\"byteOffset\":" + std::to_string(off) +
             ",\"byteLength\":" + std::to_string(bytes) + "}";
    return view++;
  };
  for (std::size_t k = 0; k < prims.size(); ++k) {
    const MiPrim& p = prims[k];
    const int pv = add_view(p.pos.data(), p.pos.size() * 4);
    float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
    for (std::size_t i = 0; i < p.pos.size(); ++i) {
      lo[i % 3] = std::fmin(lo[i % 3], p.pos[i]);
      hi[i % 3] = std::fmax(hi[i % 3], p.pos[i]);
    }
    const auto arr = [](const float* a) {  // appends: "[" + std::string&& trips GCC 12's -Wrestrict in unity builds
      std::string out(1, '[');
      for (int i = 0; i < 3; ++i) out.append(std::to_string(a[i])).append(i < 2 ? "," : "]");
      return out;
    };
    const auto add_acc = [&](int v, std::size_t count, const char* type, int comp, const std::string& extra) {
      const std::size_t id = std::count(accessors.begin(), accessors.end(), '{');
      accessors += std::string(accessors.empty() ? "" : ",") + "{\"bufferView\":" + std::to_string(v) +
                   ",\"componentType\":" + std::to_string(comp) + ",\"count\":" + std::to_string(count) +
                   ",\"type\":\"" + type + "\"" + extra + "}";
      return id;
    };
    const std::size_t pa = add_acc(pv, p.pos.size() / 3, "VEC3", 5126, ",\"min\":" + arr(lo) + ",\"max\":" + arr(hi));
    std::string attrs = "\"POSITION\":" + std::to_string(pa);
    if (!p.uv.empty()) {
      const int uvv = add_view(p.uv.data(), p.uv.size() * 4);
      attrs += ",\"TEXCOORD_0\":" + std::to_string(add_acc(uvv, p.uv.size() / 2, "VEC2", 5126, ""));
    }
    const int iv = add_view(p.idx.data(), p.idx.size() * 4);
    const std::size_t ia = add_acc(iv, p.idx.size(), "SCALAR", 5125, "");
    meshes += std::string(k ? "," : "") + "{\"primitives\":[{\"attributes\":{" + attrs + "},\"indices\":" +
              std::to_string(ia) + ",\"material\":" + std::to_string(p.material) + "}]}";
    nodes += std::string(k ? "," : "") + "{\"mesh\":" + std::to_string(k) + (node_trs.empty() ? "" : "," + node_trs) + "}";
    scene_nodes += std::string(k ? "," : "") + std::to_string(k);
  }
  if (glb_bin) *glb_bin = bin;
  std::string mats;
  for (int m = 0; m < materials; ++m) mats += std::string(m ? "," : "") + "{\"name\":\"m" + std::to_string(m) + "\"}";
  return "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[" + scene_nodes + "]}],\"nodes\":[" +
         nodes + "],\"meshes\":[" + meshes + "],\"materials\":[" + mats + "],\"buffers\":[{\"byteLength\":" +
         std::to_string(bin.size()) +
         (glb_bin ? std::string() : ",\"uri\":\"data:application/octet-stream;base64," + mi_base64(bin) + "\"") +
         "}],\"bufferViews\":[" + views + "],\"accessors\":[" + accessors + "]}";
}

std::string mi_write(const std::string& name, const std::string& text) {
  const std::string path = (std::filesystem::temp_directory_path() / ("vtsim_mi_" + name)).string();
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

MiPrim mi_quad(float x0, float y0, float size, int material, bool with_uv = true) {
  MiPrim p;
  p.pos = {x0, y0, 0, x0 + size, y0, 0, x0 + size, y0 + size, 0, x0, y0 + size, 0};
  if (with_uv) p.uv = {0, 0, 1, 0, 1, 1, 0, 1};
  p.idx = {0, 1, 2, 0, 2, 3};
  p.material = material;
  return p;
}

MeshImportOptions mi_z_up() {
  MeshImportOptions o;
  o.up = "z";
  return o;
}

void mi_expect_error(const std::string& path, const MeshImportOptions& o, const std::string& what) {
  try {
    import_mesh(path, o, 1 << 20, 1 << 20);
    FAIL("expected InputError for " << path);
  } catch (const InputError& e) {
    const std::string msg = e.what();
    CAPTURE(msg);
    CHECK(msg.find(path) != std::string::npos);
    CHECK(msg.find(what) != std::string::npos);
  }
}

}  // namespace

TEST_CASE("mesh import: glTF node transform (translation, rotation, scale) and the up axis") {
  MiPrim p;
  p.pos = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  p.uv = {0, 0, 1, 0, 0, 1};
  p.idx = {0, 1, 2};
  // 90° about y, scale 2, then +(10, 20, 30): file point (1, 0, 0) -> (0, 0, -2) -> (10, 20, 28),
  // (0, 1, 0) -> (0, 2, 0) -> (10, 22, 30).
  const std::string path = mi_write("trs.gltf", mi_gltf({p}, 1,
                                                        "\"translation\":[10,20,30],\"rotation\":[0,0.70710678118654752,0,"
                                                        "0.70710678118654752],\"scale\":[2,2,2]"));
  MeshImportOptions o;  // auto: y-up for glTF
  o.unit_m = 0.5;
  MeshImportStats st;
  const Mesh m = import_mesh(path, o, 1 << 20, 1 << 20, &st);
  REQUIRE(m.tris.size() == 1);
  CHECK(st.meshes == 1);
  const glm::dvec3 want[3] = {{10, 20, 30}, {10, 20, 28}, {10, 22, 30}};  // file frame
  for (int c = 0; c < 3; ++c) {
    const glm::dvec3 w = mesh_file_to_world(o, path, want[c]);
    const glm::dvec3 got = m.positions[m.tris[0].p[c]];
    CAPTURE(c);
    CHECK(got.x == doctest::Approx(w.x).epsilon(1e-6));
    CHECK(got.y == doctest::Approx(w.y).epsilon(1e-6));
    CHECK(got.z == doctest::Approx(w.z).epsilon(1e-6));
  }
  // y-up to z-up: file (10, 20, 30) is world (10, −30, 20), times unit 0.5.
  CHECK(mesh_file_to_world(o, path, {10, 20, 30}) == glm::dvec3(5, -15, 10));
  CHECK(mesh_up_axis(o, path) == "y");
  CHECK(mesh_up_axis(o, "a.pk3") == "z");
  CHECK(mesh_up_axis(o, "a.OBJ") == "z");
  CHECK(mesh_up_axis(o, "a.dae") == "y");
}

TEST_CASE("mesh import: materials get disjoint power-of-two regions sized by texel density") {
  // Material 0: a 4 m quad, material 1: a 1 m quad, material 2: a 2 m quad; UVs [0, 1] each.
  const std::string path = mi_write("mats.gltf", mi_gltf({mi_quad(0, 0, 4, 0), mi_quad(10, 0, 1, 1), mi_quad(20, 0, 2, 2)}, 3));
  MeshImportOptions o = mi_z_up();
  o.texels_per_m = 16;
  const std::int64_t W = 256, H = 128;
  MeshImportStats st;
  const Mesh m = import_mesh(path, o, W, H, &st);
  CHECK(st.materials == 3);
  CHECK(st.region_scale == 1.0);
  REQUIRE(m.tris.size() == 6);
  // Each material's texel box: side = 16 texels/m × metres per period.
  struct Box {
    double x0 = 1e30, y0 = 1e30, x1 = -1e30, y1 = -1e30;
  } box[3];
  for (std::size_t k = 0; k < m.tris.size(); ++k) {
    Box& b = box[k / 2];
    for (const std::int32_t t : m.tris[k].t) {
      REQUIRE(t >= 0);
      const glm::dvec2 uv = m.uvs[static_cast<std::size_t>(t)];
      b.x0 = std::min(b.x0, uv.x * W);
      b.x1 = std::max(b.x1, uv.x * W);
      b.y0 = std::min(b.y0, uv.y * H);
      b.y1 = std::max(b.y1, uv.y * H);
    }
  }
  const double side[3] = {64, 16, 32};
  for (int k = 0; k < 3; ++k) {
    CAPTURE(k);
    CHECK(box[k].x1 - box[k].x0 == side[k]);
    CHECK(box[k].y1 - box[k].y0 == side[k]);
    CHECK(std::fmod(box[k].x0, side[k]) == 0.0);  // aligned: a quadtree cell
    CHECK(std::fmod(box[k].y0, side[k]) == 0.0);
    CHECK(box[k].x1 <= 128.0);  // inside the largest power-of-two square, 128²
    CHECK(box[k].y1 <= 128.0);
    for (int j = 0; j < k; ++j) {
      const bool apart = box[k].x1 <= box[j].x0 || box[j].x1 <= box[k].x0 || box[k].y1 <= box[j].y0 || box[j].y1 <= box[k].y0;
      CHECK(apart);
    }
  }
  // A texture too small for the wished density: all regions shrink by the same power of two.
  MeshImportStats st2;
  const Mesh m2 = import_mesh(path, o, 64, 64, &st2);
  CHECK(st2.region_scale == 0.5);
  CHECK(m2.tris.size() == 6);
  const auto warn = mesh_import_warnings(st2, path);
  REQUIRE(warn.size() == 1);
  CHECK(warn[0].find("0.5") != std::string::npos);
}

TEST_CASE("mesh import: UVs outside 0..1 are wrapped by cutting triangles at integer lines") {
  // Through assimp's OBJ reader: positions equal the UVs, so every output corner's region texel
  // can be checked against its own position.
  const std::string path = mi_write("wrap.obj",
                                    "v 0.5 0.25 0\nv 1.5 0.25 0\nv 0.5 0.75 0\n"
                                    "vt 0.5 0.25\nvt 1.5 0.25\nvt 0.5 0.75\n"
                                    "v -2.25 3.25 0\nv -2.0 3.25 0\nv -2.25 3.5 0\n"
                                    "vt -2.25 3.25\nvt -2.0 3.25\nvt -2.25 3.5\n"
                                    "f 1/1 2/2 3/3\nf 4/4 5/5 6/6\n");
  MeshImportOptions o = mi_z_up();
  o.texels_per_m = 64;  // one material, 1.25 m² of world per 1.25 UV² -> 64 texels a period
  const std::int64_t W = 1024, H = 1024;
  MeshImportStats st;
  const Mesh m = import_mesh(path, o, W, H, &st);
  CHECK(st.split_triangles == 1);  // the first; the second lies in one cell, (−3, 3)
  CHECK(st.materials == 1);
  // The cut at u = 1 leaves a triangle (u >= 1) and a quad (u <= 1) = 3 triangles, plus the second.
  REQUIRE(m.tris.size() == 4);
  double area = 0.0;
  for (const Mesh::Tri& t : m.tris) {
    const glm::dvec3 a = m.positions[t.p[0]], b = m.positions[t.p[1]], c = m.positions[t.p[2]];
    area += 0.5 * glm::length(glm::cross(b - a, c - a));
    const glm::dvec3 cen = (a + b + c) / 3.0;
    const glm::dvec2 cell(std::floor(cen.x), std::floor(cen.y));
    for (int k = 0; k < 3; ++k) {
      const glm::dvec3 p = m.positions[t.p[k]];
      const glm::dvec2 uv = m.uvs[static_cast<std::size_t>(t.t[k])];
      // region 64 texels at the origin: texel = 64 · (u − cell)
      CHECK(uv.x * W == doctest::Approx(64.0 * (p.x - cell.x)).epsilon(1e-12));
      CHECK(uv.y * H == doctest::Approx(64.0 * (p.y - cell.y)).epsilon(1e-12));
      CHECK(uv.x * W >= 0.0);
      CHECK(uv.x * W <= 64.0);
    }
  }
  CHECK(area == doctest::Approx(0.25 + 0.03125));  // nothing lost by the cuts
  // A triangle spanning more than kMaxWrapCells periods is kept untextured and counted.
  const std::string wide = mi_write("wide.obj", "v 0 0 0\nv 100 0 0\nv 0 1 0\nvt 0 0\nvt 100 0\nvt 0 1\nf 1/1 2/2 3/3\n");
  MeshImportStats st2;
  const Mesh m2 = import_mesh(wide, o, W, H, &st2);
  REQUIRE(m2.tris.size() == 1);
  CHECK(m2.tris[0].t[0] == -1);
  CHECK(st2.too_many_periods == 1);
  CHECK(mesh_import_warnings(st2, wide).at(0).find("UV periods") != std::string::npos);
}

TEST_CASE("mesh import: parts without UVs follow mesh_no_uv") {
  const std::string path = mi_write("nouv.gltf", mi_gltf({mi_quad(0, 0, 1, 0), mi_quad(5, 0, 2, 0, false)}, 1));
  MeshImportOptions o = mi_z_up();
  MeshImportStats st;
  Mesh m = import_mesh(path, o, 1 << 10, 1 << 10, &st);  // untextured (default)
  REQUIRE(m.tris.size() == 4);
  CHECK(st.no_uv_untextured == 2);
  int untextured = 0;
  for (const Mesh::Tri& t : m.tris) untextured += t.t[0] < 0;
  CHECK(untextured == 2);
  CHECK(mesh_import_warnings(st, path).size() == 1);

  o.no_uv = "skip";
  m = import_mesh(path, o, 1 << 10, 1 << 10, &st);
  CHECK(m.tris.size() == 2);
  CHECK(st.no_uv_skipped == 2);

  o.no_uv = "planar";
  o.planar_m = 0.5;  // the 2 m quad spans 4 periods a side: cut into 16 cells
  o.texels_per_m = 8;
  m = import_mesh(path, o, 1 << 10, 1 << 10, &st);
  CHECK(st.no_uv_planar == 2);
  CHECK(st.split_triangles == 2);
  for (const Mesh::Tri& t : m.tris) CHECK(t.t[0] >= 0);

  o.no_uv = "error";
  mi_expect_error(path, o, "no UV set 0");
  o.no_uv = "sometimes";
  CHECK_THROWS_AS(import_mesh(path, o, 1 << 10, 1 << 10), InputError);
}

TEST_CASE("mesh import: Collada's up_axis and unit are applied by assimp, auto = y") {
  const std::string dae =
      "<?xml version=\"1.0\"?>\n<COLLADA xmlns=\"http://www.collada.org/2005/11/COLLADASchema\" version=\"1.4.1\">\n"
      "<asset><unit meter=\"0.01\" name=\"centimeter\"/><up_axis>Z_UP</up_axis></asset>\n"
      "<library_geometries><geometry id=\"g\"><mesh>\n"
      "<source id=\"p\"><float_array id=\"pa\" count=\"9\">0 0 0 100 0 0 0 0 100</float_array>\n"
      "<technique_common><accessor source=\"#pa\" count=\"3\" stride=\"3\"><param name=\"X\" type=\"float\"/>"
      "<param name=\"Y\" type=\"float\"/><param name=\"Z\" type=\"float\"/></accessor></technique_common></source>\n"
      "<vertices id=\"v\"><input semantic=\"POSITION\" source=\"#p\"/></vertices>\n"
      "<triangles count=\"1\"><input semantic=\"VERTEX\" source=\"#v\" offset=\"0\"/><p>0 1 2</p></triangles>\n"
      "</mesh></geometry></library_geometries>\n"
      "<library_visual_scenes><visual_scene id=\"s\"><node id=\"n\"><instance_geometry url=\"#g\"/></node>"
      "</visual_scene></library_visual_scenes>\n<scene><instance_visual_scene url=\"#s\"/></scene>\n</COLLADA>\n";
  const std::string path = mi_write("up.dae", dae);
  // assimp 5.2.5 crashes on an array holding values with count 0: refused before assimp reads it.
  std::string bad = dae;
  bad.replace(bad.find("count=\"9\""), 9, "count=\"0\"");
  mi_expect_error(mi_write("count0.dae", bad), MeshImportOptions{}, "count is 0 or not a number");
  bad.replace(bad.find("count=\"0\""), 9, "count=\"x\"");
  mi_expect_error(mi_write("countx.dae", bad), MeshImportOptions{}, "<float_array>");
  MeshImportStats st;
  const Mesh m = import_mesh(path, MeshImportOptions{}, 1 << 10, 1 << 10, &st);
  REQUIRE(m.tris.size() == 1);
  // The file's (0, 0, 100) cm with z up is 1 m up in vtsim's z-up world.
  glm::dvec3 top = m.positions[m.tris[0].p[0]];
  for (const auto p : m.tris[0].p)
    if (m.positions[p].z > top.z) top = m.positions[p];
  CHECK(top.z == doctest::Approx(1.0));
  CHECK(std::fabs(top.x) < 1e-9);
  CHECK(std::fabs(top.y) < 1e-9);
  CHECK(m.tris[0].t[0] == -1);  // no UVs: untextured
}

TEST_CASE("mesh import: bad files are InputErrors naming the file") {
  const MeshImportOptions o = mi_z_up();
  const std::string good = mi_gltf({mi_quad(0, 0, 1, 0)}, 1);
  mi_expect_error(mi_write("trunc.gltf", good.substr(0, good.size() / 2)), o, "assimp");
  mi_expect_error(mi_write("garbage.glb", std::string("\x01\x02garbage\xff\xfe not a scene", 22)), o, "assimp");
  mi_expect_error(mi_write("garbage.xyz", "not a scene at all\n"), o, "assimp");
  mi_expect_error("/nonexistent/vtsim_mi.gltf", o, "cannot open");
  // Formats outside issue 28's five are refused: PLY's reader hangs on corrupted headers.
  mi_expect_error(mi_write("tri.ply",
                           "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                           "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                           "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"),
                  o, "No suitable reader");
  // A scene without meshes, and one whose only triangle is NaN.
  mi_expect_error(mi_write("empty.gltf", "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{}]}"), o,
                  "");
  MiPrim nan = mi_quad(0, 0, 1, 0);
  nan.pos[0] = std::numeric_limits<float>::quiet_NaN();
  mi_expect_error(mi_write("nan.gltf", mi_gltf({nan}, 1)), o, "no triangles");
  // Half bad: the NaN corner drops one triangle, counted in a warning naming the file.
  nan.idx = {0, 1, 2, 1, 2, 3};
  MiPrim half = nan;
  half.idx = {1, 2, 3, 0, 1, 2};
  const std::string hp = mi_write("half.gltf", mi_gltf({half}, 1));
  MeshImportStats st;
  const Mesh m = import_mesh(hp, o, 1 << 10, 1 << 10, &st);
  CHECK(m.tris.size() == 1);
  CHECK(st.non_finite == 1);
  const auto w = mesh_import_warnings(st, hp);
  REQUIRE(w.size() == 1);
  CHECK(w[0] == hp + ": 1 of 2 triangles skipped: a coordinate NaN/inf or beyond ±1e12 m, or a UV beyond ±1e9");
  // Huge coordinates likewise; and the triangle limit.
  MiPrim huge = mi_quad(0, 0, 1, 0);
  huge.pos[3] = 1e30f;
  MeshImportStats st3;
  import_mesh(mi_write("huge.gltf", mi_gltf({huge}, 1)), o, 1 << 10, 1 << 10, &st3);
  CHECK(st3.non_finite == 1);  // vertex 1 is in the first triangle only
  MeshImportOptions lim = o;
  lim.max_triangles = 1;
  mi_expect_error(mi_write("limit.gltf", good), lim, "more than 1 triangles");
  lim.max_triangles = 2;
  lim.max_bytes = 10;
  mi_expect_error(mi_write("limit.gltf", good), lim, "larger than 10");
}

TEST_CASE("mesh scene: mesh_loader picks the reader, the scene renders an imported glTF") {
  SceneConfig cfg;
  cfg.kind = "mesh";
  cfg.file = "x.obj";
  CHECK(mesh_loader_for(cfg) == "obj");
  cfg.file = "x.GLB";
  CHECK(mesh_loader_for(cfg) == "assimp");
  cfg.mesh_loader = "obj";
  CHECK(mesh_loader_for(cfg) == "obj");
  cfg.mesh_loader = "nope";
  CHECK_THROWS_AS(mesh_loader_for(cfg), InputError);
  cfg.mesh_loader = "auto";
  cfg.file = mi_write("scene.gltf", mi_gltf({mi_quad(0, 0, 64, 0), mi_quad(0, 64, 64, 1)}, 2));
  cfg.mesh_up = "z";
  cfg.size_x_m = cfg.size_y_m = 64.0;
  cfg.texels_per_m = 16.0;
  const auto scene = make_scene(cfg);
  CHECK(scene->texture().width == 1024);
  CHECK(dynamic_cast<const MeshScene&>(*scene).triangle_count() == 4);
  // Two materials of 1024² texels wished in a 1024² texture: both halved, and said so.
  REQUIRE(scene->load_warnings().size() == 1);
  CHECK(scene->load_warnings()[0].find("0.5 of the wished texel density") != std::string::npos);
}

TEST_CASE("mesh import: Quake 3 pk3 (assimp 5.2.5's faces rebuilt from vertex triples, clockwise fronts)") {
  // tests/data/make_quad_q3_pk3.py: one 64 × 32-unit quad at z = 8, texture u 0..2 (tiling twice).
  const std::string path = std::string(VTSIM_TEST_DATA) + "/quad_q3.pk3";
  MeshImportOptions o;  // auto: z up for .pk3
  o.unit_m = 0.0254;
  o.texels_per_m = 64;
  MeshImportStats st;
  const Mesh m = import_mesh(path, o, 1 << 10, 1 << 10, &st);
  CHECK(st.rebuilt_faces == 2);
  CHECK(st.bad_index == 0);
  CHECK(st.split_triangles == 2);  // both span u = 1
  double area = 0.0;
  for (const Mesh::Tri& t : m.tris) {
    const glm::dvec3 a = m.positions[t.p[0]], b = m.positions[t.p[1]], c = m.positions[t.p[2]];
    const glm::dvec3 n = glm::cross(b - a, c - a);
    CHECK(n.z > 0.0);  // the front faces up, as the map's floor
    CHECK(a.z == doctest::Approx(8 * 0.0254));
    area += 0.5 * glm::length(n);
    CHECK(t.t[0] >= 0);
  }
  CHECK(area == doctest::Approx(64 * 32 * 0.0254 * 0.0254));
  CHECK(mesh_import_warnings(st, path).empty());
}

TEST_CASE("mesh import: GLB (binary glTF) reads like the same .gltf") {
  const std::vector<MiPrim> prims = {mi_quad(0, 0, 2, 0), mi_quad(5, 0, 1, 1)};
  const std::string text = mi_gltf(prims, 2, "\"translation\":[1,2,3]");
  std::string bin;
  std::string json = mi_gltf(prims, 2, "\"translation\":[1,2,3]", &bin);
  while (json.size() % 4) json += ' ';  // chunks are 4-byte aligned (glTF 2.0 §4.4)
  while (bin.size() % 4) bin += '\0';
  std::string glb = "glTF";
  const auto u32 = [&glb](std::uint32_t v) {
    for (int k = 0; k < 4; ++k) glb += static_cast<char>((v >> (8 * k)) & 0xff);
  };
  u32(2);
  u32(static_cast<std::uint32_t>(12 + 8 + json.size() + 8 + bin.size()));
  u32(static_cast<std::uint32_t>(json.size()));
  glb += "JSON";
  glb += json;
  u32(static_cast<std::uint32_t>(bin.size()));
  glb += std::string("BIN\0", 4);
  glb += bin;
  const MeshImportOptions o = mi_z_up();
  const Mesh a = import_mesh(mi_write("same.gltf", text), o, 1 << 10, 1 << 10);
  const Mesh b = import_mesh(mi_write("same.glb", glb), o, 1 << 10, 1 << 10);
  REQUIRE(a.tris.size() == 4);
  REQUIRE(b.tris.size() == a.tris.size());
  for (std::size_t k = 0; k < a.tris.size(); ++k)
    for (int c = 0; c < 3; ++c) {
      CHECK(a.positions[a.tris[k].p[c]] == b.positions[b.tris[k].p[c]]);
      CHECK(a.uvs[static_cast<std::size_t>(a.tris[k].t[c])] == b.uvs[static_cast<std::size_t>(b.tris[k].t[c])]);
    }
  CHECK(a.positions[a.tris[0].p[0]] == glm::dvec3(1, 2, 3));  // the node's translation, z up as asked
}
