#pragma once
// Scene files through assimp (glTF 2.0 / GLB, FBX, OBJ, Collada, Quake 3 .pk3 and whatever else
// assimp 5.2 reads) into one Mesh whose UVs span one virtual texture: each material owns a
// power-of-two square region of it, tiling UVs wrapped into that region (docs/view.md, "Scenes").
#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "sim/view/mesh.h"

namespace vtsim {

struct MeshImportOptions {
  double unit_m = 1.0;           // metres per file unit (Quake 3: 0.0254, one inch)
  std::string up = "auto";       // the file's up axis: "auto", "y" or "z" (vtsim's world is z-up)
  unsigned uv_set = 0;           // assimp UV channel read (Quake 3: 0 = texture, 1 = lightmap)
  std::string no_uv = "untextured";  // parts without that channel: "untextured", "skip", "planar", "error"
  double planar_m = 1.0;         // "planar": metres of world per UV period of the projection
  double texels_per_m = 128.0;   // wished level-0 density of the material regions (lowered to fit)
  std::uint64_t max_bytes = std::uint64_t{2} << 30;  // file size (assimp reads it whole)
  std::uint64_t max_triangles = 16'000'000;            // after triangulation and wrapping
};

// What import_mesh read and dropped; counts are triangles unless named otherwise.
struct MeshImportStats {
  std::uint64_t meshes = 0;              // assimp meshes instanced by the node tree
  std::uint64_t materials = 0;           // materials given a region of the texture
  std::uint64_t read = 0;                // triangles read (faces fanned), before any drop
  std::uint64_t triangles = 0;           // kept (after wrapping splits)
  std::uint64_t split_triangles = 0;     // triangles cut at integer UV lines (wrapping)
  std::uint64_t rebuilt_faces = 0;       // Quake 3: faces taken from vertex triples (assimp 5.2.5's indices are wrong)
  std::uint64_t bad_index = 0;           // faces with a vertex index out of range (dropped)
  std::uint64_t non_finite = 0;          // a corner NaN/inf or beyond ±1e12 m, or UV beyond ±1e9 (dropped)
  std::uint64_t degenerate = 0;          // zero area, or a sliver whose plane is noise (dropped)
  std::uint64_t not_polygons = 0;        // point and line primitives (ignored)
  std::uint64_t no_uv_untextured = 0;    // kept as untextured occluders (no_uv = untextured)
  std::uint64_t no_uv_skipped = 0;       // dropped (no_uv = skip)
  std::uint64_t no_uv_planar = 0;        // textured by planar projection (no_uv = planar)
  std::uint64_t too_many_periods = 0;    // spanning > kMaxWrapCells UV periods: kept untextured
  double region_scale = 1.0;             // texel density reached / wished (1, or 2^-k to fit)
};

// A triangle spanning more UV periods (cells of the integer grid its UV box covers) than this is
// not cut but kept as an untextured occluder and counted: 64 pieces already cost 64× its memory.
inline constexpr int kMaxWrapCells = 64;

// Reads `path` with assimp (no post-processing: assimp 5.2.5's Triangulate and
// JoinIdenticalVertices crash on its own Quake 3 output; everything is validated here instead),
// walks the node tree applying node transforms in double, then mesh_file_to_world. Faces are
// fanned into triangles; bad faces (index out of range, non-finite or huge coordinates, zero area)
// are dropped and counted. `extent` is the virtual texture the regions are laid out in.
// Throws InputError(path, ...) with assimp's own message for a file it refuses, for a file larger
// than max_bytes, for no triangle left, for more than max_triangles, for a part without UVs under
// no_uv = "error", and for more materials than the texture has texels; InputError naming the
// option for bad options.
Mesh import_mesh(const std::string& path, const MeshImportOptions& opt, std::int64_t extent_w,
                 std::int64_t extent_h, MeshImportStats* stats = nullptr);

// The up axis "auto" resolves to for a file: "y" for glTF/GLB, FBX and Collada (their specs; assimp
// already turns Collada's up_axis and unit into y-up metres), "z" for everything else (Quake 3, and
// OBJ by vtsim's convention).
std::string mesh_up_axis(const MeshImportOptions& opt, const std::string& path);

// The map import_mesh applies to a point after the node transforms: y-up → z-up rotation
// (x, y, z) → (x, −z, y) when the up axis is y, then × unit_m. For spawn points and the like in
// the same frame as the imported mesh.
glm::dvec3 mesh_file_to_world(const MeshImportOptions& opt, const std::string& path, glm::dvec3 p);

// One line per kind of dropped input, naming path and count (empty when nothing was dropped).
std::vector<std::string> mesh_import_warnings(const MeshImportStats& stats, const std::string& path);

struct SceneConfig;
// The reader the "mesh" scene uses for cfg.file under cfg.mesh_loader: "obj" (load_obj: vt spans
// the whole texture, errors name path:line), "assimp" (import_mesh), "auto" = obj for a .obj file,
// assimp for anything else. Throws InputError("mesh_loader", ...) for another value.
std::string mesh_loader_for(const SceneConfig& cfg);
// cfg's import options (mesh_* fields, texels_per_m).
MeshImportOptions mesh_import_options(const SceneConfig& cfg);

// Every file assimp opens to import `path` (the file itself, an OBJ's .mtl, a glTF's .bin
// buffers, ...), sorted and unique: what a scene's identity must cover (a sweep's, docs/sweep.md).
// Textures are not among them (import_mesh reads UVs, never images). Empty when assimp cannot
// read the file (the replay then says why).
std::vector<std::string> mesh_import_files(const std::string& path);

}  // namespace vtsim
