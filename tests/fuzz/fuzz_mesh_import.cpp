// Scene files through assimp (sim/view/mesh_import.h, scene.kind = mesh): the input is written
// with the extension its first bytes suggest (glTF JSON, GLB, Collada/XML, PLY (refused: not a
// scene format import_mesh keeps; its reader hung on corrupted headers), a zip = Quake 3
// .pk3, FBX, else OBJ) and imported with options drawn from its length (the UV policy and up
// axis). An accepted mesh must build a MeshScene: whatever assimp returns, import_mesh validates
// it into triangles MeshScene accepts (finite, non-degenerate, indices in range). Parsing is
// assimp's own; this target checks what vtsim does with its output.
#include <cstring>
#include <optional>
#include <stdexcept>
#include <string>

#include "fuzz_targets.h"
#include "sim/view/mesh.h"
#include "sim/view/mesh_import.h"
#include "sim/view/scene_mesh.h"

namespace vtsim::fuzz {

void mesh_import(const std::uint8_t* data, std::size_t size) {
  auto starts = [&](const char* magic, std::size_t n) { return size >= n && std::memcmp(data, magic, n) == 0; };
  const char* ext = starts("{", 1)              ? "gltf"
                    : starts("glTF", 4)         ? "glb"
                    : starts("<", 1)            ? "dae"
                    : starts("ply", 3)          ? "ply"
                    : starts("PK\x03\x04", 4)   ? "pk3"
                    : starts("Kaydara FBX", 11) ? "fbx"
                    : starts("; FBX", 5)        ? "fbx"
                                                : "obj";
  const std::string path = input_file(data, size, ext);
  static const char* const kPolicies[] = {"untextured", "skip", "planar", "error"};
  MeshImportOptions o;
  o.no_uv = kPolicies[size % 4];
  o.up = (size / 4) % 2 ? "y" : "auto";
  o.planar_m = 0.25;
  o.texels_per_m = 64.0;
  o.max_triangles = 4096;  // keeps a run fast; the limit itself is tested (InputError)
  o.max_bytes = 1 << 20;
  const TextureExtent ext_tex{1 << 12, 1 << 10};
  std::optional<Mesh> mesh;
  expect_accept_or_reject("mesh_import", [&] { mesh = import_mesh(path, o, ext_tex.width, ext_tex.height); });
  if (!mesh) return;
  must_succeed("mesh_import", "building a MeshScene from an imported mesh", [&] {
    for (const glm::dvec2& uv : mesh->uvs)
      if (!(uv.x >= 0.0 && uv.x <= 1.0 && uv.y >= 0.0 && uv.y <= 1.0))
        throw std::logic_error("a UV outside the texture after wrapping");
    const MeshScene scene(*mesh, ext_tex);
    (void)scene;
  });
}

}  // namespace vtsim::fuzz
