#pragma once
// Triangle meshes with unique UVs into one virtual texture (Yao 2011: every surface owns its own
// region of the megatexture), from a Wavefront OBJ file or the test-town generator.
#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace vtsim {

struct Mesh {
  struct Tri {
    std::uint32_t p[3];  // indices into positions, counter-clockwise seen from the front
    std::int32_t t[3];   // indices into uvs, or −1 for all three when the face has no texture
  };
  // An axis-aligned box, world metres; infinite bounds make a slab or a half-space.
  struct Box {
    glm::dvec3 lo, hi;
  };
  std::vector<glm::dvec3> positions;  // world metres
  std::vector<glm::dvec2> uvs;        // texture coordinates; [0, 1) spans the virtual texture
  std::vector<Tri> tris;
  // Optional, a promise from the mesh's maker (the town generator; never an OBJ file): every ray
  // that starts outside all these boxes meets a front face before any back face — the mesh closes
  // them off, as box buildings standing on a ground that covers their footprints do. The renderer
  // then skips back faces while no box comes within the near plane's reach of the camera
  // (docs/view.md, "Scenes", mesh). Empty: no promise, back faces are always drawn.
  std::vector<Box> solids;
};

// Limits for untrusted OBJ files (InputError beyond them).
struct ObjLimits {
  std::uint64_t max_bytes = std::uint64_t{2} << 30;  // 2 GiB file
  std::uint64_t max_triangles = 16'000'000;            // ~2.7 GB of per-triangle render data
  std::uint64_t max_vertices = 64'000'000;             // v and vt statements each
};

// What load_obj read and what it skipped (documented skips, not errors).
struct ObjStats {
  std::uint64_t lines = 0;
  std::uint64_t faces = 0;                 // f statements
  std::uint64_t triangles = 0;             // kept, after fan triangulation
  std::uint64_t degenerate_skipped = 0;    // zero-area triangles (collinear or repeated corners)
  std::uint64_t untextured_faces = 0;      // faces without vt: kept as untextured occluders
  std::uint64_t ignored_statements = 0;    // vn, o, g, s, usemtl, mtllib, l, p, unknown keywords
};

// Parses v (x y z [w | r g b]), vt (u [v [w]]), f with v, v/vt, v/vt/vn or v//vn references
// (1-based, or negative = relative to the end of the list so far), polygons as fans from their
// first corner. Throws InputError("path:line", ...) for malformed numbers, NaN/inf, index 0 or out
// of range, a face mixing corners with and without vt, fewer than 3 corners, a '\' line
// continuation, a file larger than max_bytes or more vertices/triangles than the limits, and
// InputError(path, ...) for an unreadable file or one without any triangle.
Mesh load_obj(const std::string& path, ObjStats* stats = nullptr, const ObjLimits& limits = {});
// One line per kind of input load_obj dropped, naming path and the count: "path: 3 of 1200
// triangles skipped: zero area (collinear or repeated corners)". Empty when nothing was dropped.
// (Statements the renderer does not need, such as vn or usemtl, are not data dropped.)
std::vector<std::string> obj_warnings(const ObjStats& stats, const std::string& path);
// The same on text already in memory; `name` is used in error messages.
Mesh parse_obj(const std::string& text, const std::string& name, ObjStats* stats = nullptr,
               const ObjLimits& limits = {});

}  // namespace vtsim
