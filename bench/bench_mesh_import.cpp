// Scene import (sim/view/mesh_import.h) against assimp's own import, side by side in the same
// run: a generated glTF of ~10^6 triangles (a 707² grid of quads, .gltf + .bin, UVs in [0, 1],
// one material), read by Assimp::Importer::ReadFile with no post-processing (the reference), and
// by import_mesh, which includes that same ReadFile and then validates, transforms and lays the
// UVs into the material's region. Ratio = ReadFile ms / import_mesh ms; the target, ≥ 0.5, is
// issue 28's "loading ≤ 2× assimp's own import time". A second case compares the hand-written
// OBJ reader (load_obj) with import_mesh on the same grid as an OBJ (why .obj keeps its reader:
// docs/view.md, "Scenes").
//   build/bench/bench_mesh_import [--quick] [--reps N] [--json FILE] [--filter gltf]
// The params give the resulting Mesh's bytes per triangle (positions, UVs, triangles) and the
// renderer's: MeshScene::memory_bytes() of that mesh per triangle (issue 28's "mesh memory ≤ 64
// bytes per triangle": what a replay holds for the scene; the Mesh is freed after construction).
#include <fmt/core.h>
#include <unistd.h>

#include <assimp/Importer.hpp>
#include <assimp/scene.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "harness.h"
#include "sim/view/mesh.h"
#include "sim/view/mesh_import.h"
#include "sim/view/scene_mesh.h"

using namespace vtsim;
namespace fs = std::filesystem;

namespace {

struct BenchGrid {
  std::vector<float> pos, uv;
  std::vector<std::uint32_t> idx;
  int n = 0;  // quads a side
};

BenchGrid bench_grid(int n) {
  BenchGrid g;
  g.n = n;
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) {
      // A gentle relief so that no triangle is degenerate and none is coplanar with all others.
      const float fx = static_cast<float>(x), fy = static_cast<float>(y);
      g.pos.insert(g.pos.end(), {fx, 0.01f * static_cast<float>((x * 7 + y * 13) % 17), fy});
      g.uv.insert(g.uv.end(), {fx / static_cast<float>(n), fy / static_cast<float>(n)});
    }
  const auto v = [n](int x, int y) { return static_cast<std::uint32_t>(y * (n + 1) + x); };
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) g.idx.insert(g.idx.end(), {v(x, y), v(x, y + 1), v(x + 1, y + 1), v(x, y), v(x + 1, y + 1), v(x + 1, y)});
  return g;
}

void bench_write_gltf(const BenchGrid& g, const fs::path& dir) {
  const std::size_t pb = g.pos.size() * 4, ub = g.uv.size() * 4, ib = g.idx.size() * 4;
  {
    std::ofstream bin(dir / "grid.bin", std::ios::binary);
    bin.write(reinterpret_cast<const char*>(g.pos.data()), static_cast<std::streamsize>(pb));
    bin.write(reinterpret_cast<const char*>(g.uv.data()), static_cast<std::streamsize>(ub));
    bin.write(reinterpret_cast<const char*>(g.idx.data()), static_cast<std::streamsize>(ib));
  }
  const std::size_t nv = g.pos.size() / 3;
  std::ofstream(dir / "grid.gltf") << fmt::format(
      R"({{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],)"
      R"("meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}},"indices":2,"material":0}}]}}],)"
      R"("materials":[{{"name":"ground"}}],"buffers":[{{"byteLength":{},"uri":"grid.bin"}}],)"
      R"("bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{}}},{{"buffer":0,"byteOffset":{},"byteLength":{}}},)"
      R"({{"buffer":0,"byteOffset":{},"byteLength":{}}}],)"
      R"("accessors":[{{"bufferView":0,"componentType":5126,"count":{},"type":"VEC3","min":[0,0,0],"max":[{},1,{}]}},)"
      R"({{"bufferView":1,"componentType":5126,"count":{},"type":"VEC2"}},)"
      R"({{"bufferView":2,"componentType":5125,"count":{},"type":"SCALAR"}}]}})",
      pb + ub + ib, pb, pb, ub, pb + ub, ib, nv, g.n, g.n, nv, g.idx.size());
}

void bench_write_obj(const BenchGrid& g, const fs::path& path) {
  std::string s;
  for (std::size_t i = 0; i < g.pos.size(); i += 3) s += fmt::format("v {} {} {}\n", g.pos[i], g.pos[i + 1], g.pos[i + 2]);
  for (std::size_t i = 0; i < g.uv.size(); i += 2) s += fmt::format("vt {} {}\n", g.uv[i], g.uv[i + 1]);
  for (std::size_t i = 0; i < g.idx.size(); i += 3)
    s += fmt::format("f {0}/{0} {1}/{1} {2}/{2}\n", g.idx[i] + 1, g.idx[i + 1] + 1, g.idx[i + 2] + 1);
  std::ofstream(path) << s;
}

double bench_mesh_bytes(const Mesh& m) {
  return static_cast<double>(m.positions.size() * sizeof(glm::dvec3) + m.uvs.size() * sizeof(glm::dvec2) +
                             m.tris.size() * sizeof(Mesh::Tri));
}

}  // namespace

int main(int argc, char** argv) {
  bench::Harness h("mesh_import", argc, argv, 7, 3);
  const int n = h.pick(707, 224);  // 2·707² = 999,698 triangles; quick: 100,352
  const fs::path dir = fs::temp_directory_path() / fmt::format("vtsim-bench-mesh-import-{}", ::getpid());
  fs::create_directories(dir);
  const BenchGrid g = bench_grid(n);
  const double tris = static_cast<double>(g.idx.size() / 3);
  h.param("triangles", tris);
  bench_write_gltf(g, dir);
  bench_write_obj(g, dir / "grid.obj");
  const std::string gltf = (dir / "grid.gltf").string(), obj = (dir / "grid.obj").string();
  MeshImportOptions o;
  o.texels_per_m = 1.0;  // one 2^k region for the ground: the layout is not what is measured
  const std::int64_t side = std::int64_t{1} << 12;

  MeshImportStats st;
  const Mesh probe = import_mesh(gltf, o, side, side, &st);
  const double bpt = bench_mesh_bytes(probe) / static_cast<double>(probe.tris.size());
  const double scene_bpt = static_cast<double>(MeshScene(probe, TextureExtent{side, side}).memory_bytes()) /
                           static_cast<double>(probe.tris.size());
  ObjStats ost;
  const Mesh probe_obj = load_obj(obj, &ost);
  h.compare({.name = "gltf_import",
             .metric = bench::Metric::kMsPerRep,
             .work = tris,
             .params = {{"file_bytes", fs::file_size(gltf) + fs::file_size(dir / "grid.bin")},
                        {"mesh_bytes_per_triangle", bpt},
                        {"scene_bytes_per_triangle", scene_bpt},
                        {"triangles_kept", st.triangles}},
             .target_ratio = 0.5,
             .target_in_quick = true},
            {"import_mesh", {}, [&] {
               Mesh m = import_mesh(gltf, o, side, side);
               bench::do_not_optimize(m.tris.data());
             }},
            {"assimp_ReadFile", {}, [&] {
               Assimp::Importer imp;
               const aiScene* s = imp.ReadFile(gltf, 0u);
               if (!s) throw std::runtime_error(imp.GetErrorString());
               bench::do_not_optimize(s);
             }});
  h.compare({.name = "obj_hand_vs_assimp",
             .metric = bench::Metric::kMsPerRep,
             .work = tris,
             .params = {{"file_bytes", fs::file_size(obj)},
                        {"hand_mesh_bytes_per_triangle",
                         bench_mesh_bytes(probe_obj) / static_cast<double>(probe_obj.tris.size())}},
             .target_ratio = 0},
            {"load_obj", {}, [&] {
               Mesh m = load_obj(obj);
               bench::do_not_optimize(m.tris.data());
             }},
            {"import_mesh_obj", {}, [&] {
               Mesh m = import_mesh(obj, o, side, side);
               bench::do_not_optimize(m.tris.data());
             }});
  fs::remove_all(dir);
  return h.finish();
}
