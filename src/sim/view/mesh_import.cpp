// Scene files through assimp into one Mesh (mesh_import.h, docs/view.md "Scenes").
#include "sim/view/mesh_import.h"

#include <algorithm>
#include <set>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <assimp/BaseImporter.h>
#include <assimp/DefaultIOSystem.h>
#include <assimp/Importer.hpp>
#include <assimp/importerdesc.h>
#include <fmt/format.h>
#include <assimp/scene.h>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/matrix.hpp>
#include <glm/vec2.hpp>
#include <glm/vec4.hpp>

#include "core/error.h"
#include "core/input_file.h"
#include "sim/view/scene.h"
#include "sim/view/scene_mesh.h"

namespace vtsim {

namespace {

constexpr double kImportMaxCoord = 1e12;  // metres: beyond any scene, far below overflow (as load_obj)
// UVs beyond ±1e9 periods: a double then keeps < 2^-22 of a period after the integer shift, a few
// texels of a 2^16 region; such a file is broken, not tiling.
constexpr double kImportMaxUv = 1e9;

std::string import_lower_ext(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  const std::size_t dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string e = path.substr(dot + 1);
  for (char& c : e) c = static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
  return e;
}

glm::dmat4 import_to_dmat(const aiMatrix4x4& m) {
  // aiMatrix4x4 is row-major (a1..a4 the first row); glm is column-major.
  return glm::dmat4(m.a1, m.b1, m.c1, m.d1, m.a2, m.b2, m.c2, m.d2, m.a3, m.b3, m.c3, m.d3, m.a4, m.b4, m.c4, m.d4);
}

bool import_finite_pos(const glm::dvec3& p) {
  return std::fabs(p.x) <= kImportMaxCoord && std::fabs(p.y) <= kImportMaxCoord && std::fabs(p.z) <= kImportMaxCoord;
}

// Zero area, or so thin (sine of the corner angle below 1e-12) that its plane is noise: load_obj's
// rule, which MeshScene's own (area > 0) then never meets.
bool import_degenerate(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
  const glm::dvec3 e1 = b - a, e2 = c - a;
  const glm::dvec3 n = glm::cross(e1, e2);
  const double n2 = glm::dot(n, n);
  return !(n2 > 1e-24 * glm::dot(e1, e1) * glm::dot(e2, e2)) || n2 == 0.0;
}

// Planar projection: the two world coordinates across the triangle's dominant normal axis.
glm::dvec2 import_planar_uv(const glm::dvec3& p, int axis, double period_m) {
  if (axis == 0) return glm::dvec2(p.y, p.z) / period_m;
  if (axis == 1) return glm::dvec2(p.x, p.z) / period_m;
  return glm::dvec2(p.x, p.y) / period_m;
}

// One node-tree instance of an assimp mesh: its vertices are positions[pos0 ...].
struct ImportInst {
  const aiMesh* mesh;
  std::uint32_t pos0;
  bool mirror;  // the transform's determinant is negative: corners swapped to keep CCW fronts
};

// A triangle kept by the first pass: positions, and the corner vertices in its aiMesh (for UVs).
struct ImportPending {
  std::uint32_t p[3];
  std::uint32_t v[3];
  std::uint32_t inst;
};

// A polygon corner while cutting at integer UV lines.
struct ImportCorner {
  glm::dvec3 p;
  glm::dvec2 uv;
};

bool import_corner_less(const ImportCorner& a, const ImportCorner& b) {
  if (a.p.x != b.p.x) return a.p.x < b.p.x;
  if (a.p.y != b.p.y) return a.p.y < b.p.y;
  if (a.p.z != b.p.z) return a.p.z < b.p.z;
  if (a.uv.x != b.uv.x) return a.uv.x < b.uv.x;
  return a.uv.y < b.uv.y;
}

// Sutherland–Hodgman against uv[axis] >= c (keep_above) or <= c. The cut point is computed from
// the edge's endpoints in a canonical order, so that two triangles sharing the edge cut it at the
// bit-identical point (no crack).
int import_clip(const ImportCorner* in, int n, int axis, double c, bool keep_above, ImportCorner* out) {
  int m = 0;
  for (int k = 0; k < n; ++k) {
    const ImportCorner& a = in[k];
    const ImportCorner& b = in[(k + 1) % n];
    const bool ain = keep_above ? a.uv[axis] >= c : a.uv[axis] <= c;
    const bool bin = keep_above ? b.uv[axis] >= c : b.uv[axis] <= c;
    if (ain) out[m++] = a;
    if (ain != bin) {
      ImportCorner s = a, e = b;
      if (import_corner_less(e, s)) std::swap(s, e);
      const double t = (c - s.uv[axis]) / (e.uv[axis] - s.uv[axis]);
      ImportCorner q{s.p + t * (e.p - s.p), s.uv + t * (e.uv - s.uv)};
      q.uv[axis] = c;
      out[m++] = q;
    }
  }
  return m;
}

// A material's square region of the texture, texels.
struct ImportRegion {
  double x = 0.0, y = 0.0, side = 0.0;
};

std::uint32_t import_compact_bits(std::uint64_t x) {  // even bits of x -> low 32 bits (Morton)
  x &= 0x5555555555555555ull;
  x = (x | (x >> 1)) & 0x3333333333333333ull;
  x = (x | (x >> 2)) & 0x0f0f0f0f0f0f0f0full;
  x = (x | (x >> 4)) & 0x00ff00ff00ff00ffull;
  x = (x | (x >> 8)) & 0x0000ffff0000ffffull;
  x = (x | (x >> 16)) & 0x00000000ffffffffull;
  return static_cast<std::uint32_t>(x);
}

// Leaves the importer only the readers of issue 28's formats: glTF 1/2 (.gltf/.glb), FBX, OBJ,
// Collada and Quake 3 BSP (.pk3/.bsp). assimp's ~40 other readers are untested here, and one of
// them, PLY, loops forever on a corrupted header (2 of 800 mutated inputs; assimp 5.2.5): a file
// of another format is refused ("No suitable reader found") instead.
void import_keep_scene_readers(Assimp::Importer& importer) {
  static const char* const kKeep[] = {"gltf", "glb", "fbx", "obj", "dae", "pk3"};
  std::vector<Assimp::BaseImporter*> drop;
  for (std::size_t i = 0; i < importer.GetImporterCount(); ++i) {
    const aiImporterDesc* d = importer.GetImporterInfo(i);
    const std::string exts = d && d->mFileExtensions ? std::string(" ") + d->mFileExtensions + " " : "";
    bool keep = false;
    for (const char* k : kKeep) keep = keep || exts.find(std::string(" ") + k + " ") != std::string::npos;
    if (!keep) drop.push_back(importer.GetImporter(i));
  }
  // UnregisterLoader hands the reader back to the caller (the Importer deletes only the readers
  // it still holds): delete it, or every import leaks the ~40 unregistered readers (LSan).
  for (Assimp::BaseImporter* b : drop)
    if (importer.UnregisterLoader(b) == aiReturn_SUCCESS) delete b;
}

// assimp 5.2.5's Collada reader writes past an array whose count attribute is 0 or not a number
// while the element holds values (<float_array count="0">1 2 3</float_array>: a segfault, found by
// mutating tests/fuzz/corpus/mesh_import/z_up_centimetres.dae). Such a file is refused here first.
void import_check_collada(const std::string& path) {
  const std::string text = read_regular_file(path, std::uint64_t{2} << 30, "more than the limit for a scene file");
  const auto is_alpha = [](char ch) { return (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z'); };
  for (std::size_t pos = text.find("_array"); pos != std::string::npos; pos = text.find("_array", pos + 1)) {
    std::size_t b = pos;
    while (b > 0 && is_alpha(text[b - 1])) --b;
    if (b == 0 || text[b - 1] != '<') continue;  // not an element's start tag
    const std::size_t gt = text.find('>', pos);
    if (gt == std::string::npos) return;  // assimp refuses the broken XML itself
    if (text[gt - 1] == '/') continue;    // empty element
    const std::string_view tag(text.data() + b, gt - b);
    std::size_t digits = 0;
    bool positive = false;
    if (const std::size_t c = tag.find("count="); c != std::string_view::npos && c + 7 <= tag.size()) {
      for (std::size_t k = c + 7; k < tag.size() && tag[k] >= '0' && tag[k] <= '9'; ++k, ++digits)
        positive = positive || tag[k] != '0';
    }
    if (digits > 0 && positive) continue;
    const std::size_t end = text.find('<', gt);
    const std::string_view body(text.data() + gt + 1, (end == std::string::npos ? text.size() : end) - gt - 1);
    if (body.find_first_not_of(" \t\r\n") != std::string_view::npos)
      throw InputError(path, "Collada: <" + std::string(tag.substr(0, tag.find(' '))) +
                                 "> holds values but its count is 0 or not a number (assimp 5.2.5 crashes on it)");
  }
}

// import_mesh's options and extent, checked before the file is opened.
void import_check_options(const MeshImportOptions& opt, std::int64_t extent_w, std::int64_t extent_h) {
  if (!(opt.unit_m > 0.0) || !std::isfinite(opt.unit_m) || opt.unit_m > 1e6)
    throw InputError("mesh_unit_m", "must be finite, > 0 and <= 1e6");
  if (!(opt.planar_m > 0.0) || !std::isfinite(opt.planar_m)) throw InputError("mesh_planar_m", "must be finite and > 0");
  if (!(opt.texels_per_m > 0.0) || !std::isfinite(opt.texels_per_m))
    throw InputError("texels_per_m", "must be finite and > 0");
  if (opt.no_uv != "untextured" && opt.no_uv != "skip" && opt.no_uv != "planar" && opt.no_uv != "error")
    throw InputError("mesh_no_uv", "must be \"untextured\", \"skip\", \"planar\" or \"error\", not \"" + opt.no_uv + "\"");
  if (opt.uv_set >= AI_MAX_NUMBER_OF_TEXTURECOORDS)
    throw InputError("mesh_uv_set", "must be below " + std::to_string(AI_MAX_NUMBER_OF_TEXTURECOORDS));
  if (extent_w < 1 || extent_h < 1) throw InputError("texture", "extent must be at least 1×1");
}

// Pass 1 of import_mesh: the meshes the node tree instances (explicit stack: a file's depth is
// untrusted), their vertices in world space in `out`, and their polygons as fans of triangles,
// pending their UVs; each material's world and UV areas for its region.
struct ImportFound {
  std::vector<ImportInst> insts;
  std::vector<ImportPending> pend;
  std::uint32_t n_mat = 1;
  std::vector<double> area_w, area_uv;  // per material: m², UV periods²
};

ImportFound import_instances(const aiScene* sc, const glm::dmat4& world, const std::string& path, const MeshImportOptions& opt,
                             Mesh& out, MeshImportStats& st) {
  const bool q3 = import_lower_ext(path) == "pk3" || import_lower_ext(path) == "bsp";
  const bool no_uv_skip = opt.no_uv == "skip", no_uv_untextured = opt.no_uv == "untextured";
  ImportFound r;
  std::vector<ImportInst>& insts = r.insts;
  std::vector<ImportPending>& pend = r.pend;
  const std::uint32_t n_mat = r.n_mat = std::max(1u, sc->mNumMaterials);
  r.area_w.assign(n_mat, 0.0);
  r.area_uv.assign(n_mat, 0.0);
  std::vector<double>& area_w = r.area_w;
  std::vector<double>& area_uv = r.area_uv;
  std::vector<std::pair<const aiNode*, glm::dmat4>> stack{{sc->mRootNode, world}};
  std::uint64_t instanced = 0;  // faces instanced by the node tree: a bound against instancing bombs
  struct Found {
    const aiMesh* mesh;
    glm::dmat4 xf;
    bool mirror;
  };
  std::vector<Found> found;
  std::uint64_t n_vertices = 0;
  while (!stack.empty()) {
    const auto [node, parent] = stack.back();
    stack.pop_back();
    const glm::dmat4 xf = parent * import_to_dmat(node->mTransformation);
    for (unsigned c = node->mNumChildren; c-- > 0;)  // reversed: children are visited in file order
      if (node->mChildren && node->mChildren[c]) stack.emplace_back(node->mChildren[c], xf);
    const bool mirror = glm::determinant(glm::dmat3(xf)) < 0.0;
    for (unsigned k = 0; k < node->mNumMeshes; ++k) {
      if (!node->mMeshes || node->mMeshes[k] >= sc->mNumMeshes || !sc->mMeshes) continue;
      const aiMesh* am = sc->mMeshes[node->mMeshes[k]];
      if (!am || !am->mVertices) continue;
      instanced += am->mNumFaces;
      n_vertices += am->mNumVertices;
      if (instanced > opt.max_triangles || n_vertices > 4 * opt.max_triangles + 64)
        throw InputError(path, "more than " + std::to_string(opt.max_triangles) + " triangles");
      found.push_back(Found{am, xf, mirror});
    }
  }
  out.positions.reserve(n_vertices);
  pend.reserve(instanced);
  for (const Found& fd : found) {
    const aiMesh* am = fd.mesh;
    const glm::dmat4& xf = fd.xf;
    const bool mirror = fd.mirror;
    ++st.meshes;
    const auto inst_id = static_cast<std::uint32_t>(insts.size());
    const auto pos0 = static_cast<std::uint32_t>(out.positions.size());
    insts.push_back(ImportInst{am, pos0, mirror});
    for (unsigned v = 0; v < am->mNumVertices; ++v) {
      const aiVector3D& a = am->mVertices[v];
      out.positions.push_back(glm::dvec3(xf * glm::dvec4(a.x, a.y, a.z, 1.0)));
    }
    const aiVector3D* tc = am->mTextureCoords[opt.uv_set];
    const bool has_uv = tc != nullptr;
    if (!has_uv && opt.no_uv == "error")
      throw InputError(path, "mesh \"" + std::string(am->mName.C_Str()) + "\" has no UV set " +
                                 std::to_string(opt.uv_set) + " (mesh_no_uv = \"error\")");
    const std::uint32_t mat = am->mMaterialIndex < n_mat ? am->mMaterialIndex : 0;
    // assimp 5.2.5's Quake 3 importer writes each face's three corners as consecutive vertices
    // but fills the faces' index arrays wrongly (oa_dm1: faces such as {2975341893, 22102, 0}
    // or {0, 0, 0}; 3 out of range, most of the rest degenerate). Its meshes hold exactly
    // 3 vertices per face, so the faces are rebuilt from the vertex triples.
    const bool triples = q3 && am->mNumVertices == 3u * am->mNumFaces;
    unsigned tri_idx[3] = {0, 0, 0};
    if (triples) st.rebuilt_faces += am->mNumFaces;
    for (unsigned f = 0; f < am->mNumFaces; ++f) {
      // The face's corners (not an aiFace: its destructor frees the index array).
      struct {
        unsigned mNumIndices;
        const unsigned* mIndices;
      } face{am->mFaces ? am->mFaces[f].mNumIndices : 0u, am->mFaces ? am->mFaces[f].mIndices : nullptr};
      if (triples) {
        tri_idx[0] = 3 * f;
        tri_idx[1] = 3 * f + 2;  // Quake 3 winds front faces clockwise
        tri_idx[2] = 3 * f + 1;
        face = {3u, tri_idx};
      }
      if (face.mNumIndices < 3 || !face.mIndices) {
        ++st.not_polygons;
        continue;
      }
      bool ok = true;
      for (unsigned c = 0; c < face.mNumIndices; ++c) ok = ok && face.mIndices[c] < am->mNumVertices;
      if (!ok) {
        st.read += face.mNumIndices - 2;
        st.bad_index += face.mNumIndices - 2;
        continue;
      }
      st.read += face.mNumIndices - 2;
      for (unsigned c = 1; c + 1 < face.mNumIndices; ++c) {
        std::uint32_t v[3] = {face.mIndices[0], face.mIndices[c], face.mIndices[c + 1]};
        if (mirror) std::swap(v[1], v[2]);
        const glm::dvec3 p0 = out.positions[pos0 + v[0]], p1 = out.positions[pos0 + v[1]],
                         p2 = out.positions[pos0 + v[2]];
        bool fine = import_finite_pos(p0) && import_finite_pos(p1) && import_finite_pos(p2);
        if (fine && has_uv)
          for (const std::uint32_t i : v)
            fine = fine && std::fabs(static_cast<double>(tc[i].x)) <= kImportMaxUv &&
                   std::fabs(static_cast<double>(tc[i].y)) <= kImportMaxUv;
        if (!fine) {
          ++st.non_finite;
          continue;
        }
        const glm::dvec3 e1 = p1 - p0, e2 = p2 - p0;
        const glm::dvec3 n = glm::cross(e1, e2);
        const double n2 = glm::dot(n, n);
        if (!(n2 > 1e-24 * glm::dot(e1, e1) * glm::dot(e2, e2)) || n2 == 0.0) {  // import_degenerate
          ++st.degenerate;
          continue;
        }
        if (!has_uv && no_uv_skip) {
          ++st.no_uv_skipped;
          continue;
        }
        pend.push_back(ImportPending{{pos0 + v[0], pos0 + v[1], pos0 + v[2]}, {v[0], v[1], v[2]}, inst_id});
        if (!has_uv && no_uv_untextured) continue;
        glm::dvec2 uv[3];
        if (has_uv) {
          for (int c2 = 0; c2 < 3; ++c2) uv[c2] = glm::dvec2(tc[v[c2]].x, tc[v[c2]].y);
        } else {
          const glm::dvec3 an = glm::abs(n);
          const int axis = an.x >= an.y && an.x >= an.z ? 0 : (an.y >= an.z ? 1 : 2);
          for (int c2 = 0; c2 < 3; ++c2) uv[c2] = import_planar_uv(out.positions[pos0 + v[c2]], axis, opt.planar_m);
        }
        const glm::dvec2 d1 = uv[1] - uv[0], d2 = uv[2] - uv[0];
        area_w[mat] += 0.5 * std::sqrt(n2);
        area_uv[mat] += 0.5 * std::fabs(d1.x * d2.y - d1.y * d2.x);
      }
    }
  }
  if (pend.empty())
    throw InputError(path, "no triangles to draw (" + std::to_string(st.meshes) + " meshes instanced; " +
                               std::to_string(st.bad_index + st.non_finite + st.degenerate + st.no_uv_skipped) +
                               " triangles dropped, " + std::to_string(st.not_polygons) + " points/lines ignored)");
  return r;
}

// The regions of import_mesh: one power-of-two square per textured material in the largest
// power-of-two square S of the texture. Side ≈ texels_per_m · sqrt(world area / UV area): one UV
// period then spans about texels_per_m texels per metre, the same density on every material. All
// sides are halved together until they fit S²; packed largest first along the Morton curve, where
// equal or shrinking power-of-two squares always land aligned and disjoint (quadtree packing).
std::vector<ImportRegion> import_regions(const ImportFound& found, const std::string& path, const MeshImportOptions& opt,
                                         std::int64_t extent_w, std::int64_t extent_h, MeshImportStats& st) {
  const std::uint32_t n_mat = found.n_mat;
  const std::vector<double>& area_w = found.area_w;
  const std::vector<double>& area_uv = found.area_uv;
  const std::int64_t min_side = std::min(extent_w, extent_h);
  int s_log = 0;
  // At most 2^31 a side, so that Morton offsets fit 64 bits (a 2^31 region is 2^24 tiles wide).
  while (s_log < 31 && (std::int64_t{2} << s_log) <= min_side) ++s_log;
  std::vector<int> side_log(n_mat, -1);
  std::vector<std::uint32_t> order;
  for (std::uint32_t m = 0; m < n_mat; ++m) {
    if (!(area_w[m] > 0.0)) continue;
    const double metres_per_period = area_uv[m] > 0.0 ? std::sqrt(area_w[m] / area_uv[m]) : std::sqrt(area_w[m]);
    const double want = std::max(1.0, opt.texels_per_m * metres_per_period);
    side_log[m] = static_cast<int>(std::lround(std::log2(std::min(want, 0x1p62))));
    order.push_back(m);
  }
  st.materials = order.size();
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    return side_log[a] != side_log[b] ? side_log[a] > side_log[b] : a < b;
  });
  const auto fits = [&](int by) {  // sum of areas <= S², texels²
    long double sum = 0.0L;
    for (const std::uint32_t m : order) sum += std::ldexp(1.0L, 2 * std::max(0, side_log[m] - by));
    return sum <= std::ldexp(1.0L, 2 * s_log);
  };
  int shrink = 0;
  for (const std::uint32_t m : order) shrink = std::max(shrink, side_log[m] - s_log);
  while (!fits(shrink)) {
    if (shrink > 128)
      throw InputError(path, std::to_string(order.size()) + " materials do not fit the " + std::to_string(extent_w) +
                                 "×" + std::to_string(extent_h) + " texture (one texel each at least)");
    ++shrink;
  }
  std::vector<ImportRegion> region(n_mat);
  {
    std::uint64_t cursor = 0;  // texels² placed so far, Morton order
    for (const std::uint32_t m : order) {
      const int sl = std::max(0, side_log[m] - shrink);
      const std::uint64_t z = cursor;
      region[m] = ImportRegion{static_cast<double>(import_compact_bits(z)), static_cast<double>(import_compact_bits(z >> 1)),
                               std::ldexp(1.0, sl)};
      cursor += std::uint64_t{1} << (2 * sl);
    }
    st.region_scale = std::ldexp(1.0, -shrink);
  }
  return region;
}

// Pass 2 of import_mesh: the pending triangles with their UVs wrapped into their material's
// region, a triangle that spans several UV periods cut at the period lines.
void import_wrap(const ImportFound& found, const std::vector<ImportRegion>& region, const std::string& path,
                 const MeshImportOptions& opt, std::int64_t extent_w, std::int64_t extent_h, Mesh& out, MeshImportStats& st) {
  const bool no_uv_untextured = opt.no_uv == "untextured";
  const std::uint32_t n_mat = found.n_mat;
  const std::vector<ImportInst>& insts = found.insts;
  const std::vector<ImportPending>& pend = found.pend;
  const double W = static_cast<double>(extent_w), H = static_cast<double>(extent_h);
  out.tris.reserve(pend.size());
  out.uvs.reserve(out.positions.size());
  // Per position: the UV index made for it with the last integer shift (most corners of a tiling
  // mesh reuse their first), so untouched vertices keep one shared UV.
  std::vector<std::int32_t> uv_cache(out.positions.size(), -1);
  std::vector<std::int64_t> shift_cache(out.positions.size(), 0);
  const auto region_uv = [&](const ImportRegion& r, glm::dvec2 uv) {
    return glm::dvec2((r.x + uv.x * r.side) / W, (r.y + uv.y * r.side) / H);
  };
  const auto push_uv = [&](glm::dvec2 uv) {
    out.uvs.push_back(uv);
    return static_cast<std::int32_t>(out.uvs.size() - 1);
  };
  const auto check_count = [&] {
    if (out.tris.size() >= opt.max_triangles)
      throw InputError(path, "more than " + std::to_string(opt.max_triangles) + " triangles (after wrapping)");
  };
  ImportCorner poly_a[16], poly_b[16];
  for (const ImportPending& pt : pend) {
    const ImportInst& in = insts[pt.inst];
    const aiMesh* am = in.mesh;
    const aiVector3D* tc = am->mTextureCoords[opt.uv_set];
    const std::uint32_t mat = am->mMaterialIndex < n_mat ? am->mMaterialIndex : 0;
    check_count();
    if (!tc && no_uv_untextured) {
      ++st.no_uv_untextured;
      out.tris.push_back(Mesh::Tri{{pt.p[0], pt.p[1], pt.p[2]}, {-1, -1, -1}});
      continue;
    }
    glm::dvec2 uv[3];
    const glm::dvec3 P[3] = {out.positions[pt.p[0]], out.positions[pt.p[1]], out.positions[pt.p[2]]};
    if (tc) {
      for (int c = 0; c < 3; ++c) uv[c] = glm::dvec2(tc[pt.v[c]].x, tc[pt.v[c]].y);
    } else {
      ++st.no_uv_planar;
      const glm::dvec3 an = glm::abs(glm::cross(P[1] - P[0], P[2] - P[0]));
      const int axis = an.x >= an.y && an.x >= an.z ? 0 : (an.y >= an.z ? 1 : 2);
      for (int c = 0; c < 3; ++c) uv[c] = import_planar_uv(P[c], axis, opt.planar_m);
    }
    const ImportRegion& r = region[mat];
    const double ulo = std::min({uv[0].x, uv[1].x, uv[2].x}), uhi = std::max({uv[0].x, uv[1].x, uv[2].x});
    const double vlo = std::min({uv[0].y, uv[1].y, uv[2].y}), vhi = std::max({uv[0].y, uv[1].y, uv[2].y});
    // Cells [i, i+1) × [j, j+1) the UV box covers; a corner on an integer line belongs to the
    // cell below it when the box ends there.
    const auto i0 = static_cast<std::int64_t>(std::floor(ulo)), j0 = static_cast<std::int64_t>(std::floor(vlo));
    const std::int64_t i1 = std::max(i0, static_cast<std::int64_t>(std::ceil(uhi)) - 1);
    const std::int64_t j1 = std::max(j0, static_cast<std::int64_t>(std::ceil(vhi)) - 1);
    const std::int64_t cells = (i1 - i0 + 1) * (j1 - j0 + 1);
    if (cells == 1) {
      const glm::dvec2 shift(static_cast<double>(i0), static_cast<double>(j0));
      Mesh::Tri t{{pt.p[0], pt.p[1], pt.p[2]}, {0, 0, 0}};
      const std::int64_t key = (i0 << 32) ^ (j0 & 0xffffffff);
      for (int c = 0; c < 3; ++c) {
        const std::uint32_t q = pt.p[c];
        if (tc && uv_cache[q] >= 0 && shift_cache[q] == key) {
          t.t[c] = uv_cache[q];
          continue;
        }
        t.t[c] = push_uv(region_uv(r, uv[c] - shift));
        if (tc) {
          uv_cache[q] = t.t[c];
          shift_cache[q] = key;
        }
      }
      out.tris.push_back(t);
      continue;
    }
    if (cells > kMaxWrapCells) {
      ++st.too_many_periods;
      out.tris.push_back(Mesh::Tri{{pt.p[0], pt.p[1], pt.p[2]}, {-1, -1, -1}});
      continue;
    }
    ++st.split_triangles;
    const ImportCorner tri[3] = {{P[0], uv[0]}, {P[1], uv[1]}, {P[2], uv[2]}};
    for (std::int64_t i = i0; i <= i1; ++i) {
      for (std::int64_t j = j0; j <= j1; ++j) {
        const double fi = static_cast<double>(i), fj = static_cast<double>(j);
        int n = import_clip(tri, 3, 0, fi, true, poly_a);
        n = import_clip(poly_a, n, 0, fi + 1.0, false, poly_b);
        n = import_clip(poly_b, n, 1, fj, true, poly_a);
        n = import_clip(poly_a, n, 1, fj + 1.0, false, poly_b);
        for (int k = 1; k + 1 < n; ++k) {
          const ImportCorner* c3[3] = {&poly_b[0], &poly_b[k], &poly_b[k + 1]};
          if (import_degenerate(c3[0]->p, c3[1]->p, c3[2]->p)) continue;  // a sliver along a cut line
          check_count();
          Mesh::Tri t{};
          for (int c = 0; c < 3; ++c) {
            t.p[c] = static_cast<std::uint32_t>(out.positions.size());
            out.positions.push_back(c3[c]->p);
            t.t[c] = push_uv(region_uv(r, c3[c]->uv - glm::dvec2(fi, fj)));
          }
          out.tris.push_back(t);
        }
      }
    }
  }
}

}  // namespace

std::string mesh_up_axis(const MeshImportOptions& opt, const std::string& path) {
  if (opt.up == "y" || opt.up == "z") return opt.up;
  if (opt.up != "auto") throw InputError("mesh_up", "must be \"auto\", \"y\" or \"z\", not \"" + opt.up + "\"");
  const std::string e = import_lower_ext(path);
  return (e == "gltf" || e == "glb" || e == "fbx" || e == "dae") ? "y" : "z";
}

glm::dvec3 mesh_file_to_world(const MeshImportOptions& opt, const std::string& path, glm::dvec3 p) {
  if (mesh_up_axis(opt, path) == "y") p = glm::dvec3(p.x, -p.z, p.y);
  return p * opt.unit_m;
}

Mesh import_mesh(const std::string& path, const MeshImportOptions& opt, std::int64_t extent_w, std::int64_t extent_h,
                 MeshImportStats* stats_out) {
  import_check_options(opt, extent_w, extent_h);
  const bool y_up = mesh_up_axis(opt, path) == "y";
  {
    const RegularFile f = open_regular_file(path);
    if (f.size() > opt.max_bytes)
      throw InputError(path, std::to_string(f.size()) + " bytes, larger than " + std::to_string(opt.max_bytes) +
                                 ": more than the limit for a scene file");
  }

  // Collada, or any extension no kept reader claims (assimp then picks a reader by content).
  if (const std::string e = import_lower_ext(path);
      e != "gltf" && e != "glb" && e != "fbx" && e != "obj" && e != "pk3" && e != "bsp")
    import_check_collada(path);
  Assimp::Importer importer;
  import_keep_scene_readers(importer);
  // No post-processing: assimp 5.2.5's Triangulate / JoinIdenticalVertices segfault on its own
  // Quake 3 output (faces with indices out of range) and ValidateDataStructure refuses the whole
  // map for 3 faces of 7,532. Fans, index checks and coordinate checks are done below instead.
  const aiScene* sc = importer.ReadFile(path, 0u);
  if (!sc) throw InputError(path, std::string("assimp: ") + importer.GetErrorString());
  if (!sc->mRootNode) throw InputError(path, "assimp: the scene has no node tree");

  MeshImportStats st;
  Mesh out;
  // World = up rotation · unit scale · node transforms (mesh_file_to_world after the nodes).
  glm::dmat4 world(opt.unit_m);
  world[3][3] = 1.0;
  if (y_up) world = world * glm::dmat4(1, 0, 0, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1);

  const ImportFound found = import_instances(sc, world, path, opt, out, st);
  const std::vector<ImportRegion> region = import_regions(found, path, opt, extent_w, extent_h, st);
  import_wrap(found, region, path, opt, extent_w, extent_h, out, st);
  st.triangles = out.tris.size();
  if (out.tris.empty()) throw InputError(path, "no triangles to draw");
  if (stats_out) *stats_out = st;
  return out;
}

std::vector<std::string> mesh_import_warnings(const MeshImportStats& st, const std::string& path) {
  std::vector<std::string> out;
  const std::uint64_t read = st.read;
  const auto line = [&](std::uint64_t n, const std::string& why) {
    if (n > 0) out.push_back(path + ": " + std::to_string(n) + " of " + std::to_string(read) + " triangles " + why);
  };
  line(st.bad_index, "skipped: a vertex index out of range");
  line(st.non_finite, "skipped: a coordinate NaN/inf or beyond ±1e12 m, or a UV beyond ±1e9");
  line(st.degenerate, "skipped: zero area (collinear or repeated corners)");
  line(st.no_uv_skipped, "skipped: no UV set (mesh_no_uv = \"skip\")");
  line(st.no_uv_untextured, "have no UV set: drawn untextured, as occluders (mesh_no_uv = \"untextured\")");
  line(st.too_many_periods, "span more than " + std::to_string(kMaxWrapCells) +
                                " UV periods: drawn untextured, as occluders");
  if (st.not_polygons > 0) out.push_back(path + ": " + std::to_string(st.not_polygons) + " point or line primitives ignored");
  if (st.region_scale < 1.0)
    out.push_back(fmt::format("{}: material regions at {:g} of the wished texel density (the texture is too "
                              "small for {} materials at texels_per_m)",
                              path, st.region_scale, st.materials));
  return out;
}

namespace {
// assimp's file system, recording the name of every file a reader opens.
class RecordingIOSystem : public Assimp::DefaultIOSystem {
 public:
  explicit RecordingIOSystem(std::set<std::string>& opened) : opened_(opened) {}
  Assimp::IOStream* Open(const char* file, const char* mode) override {
    Assimp::IOStream* s = Assimp::DefaultIOSystem::Open(file, mode);
    if (s) opened_.insert(file);
    return s;
  }

 private:
  std::set<std::string>& opened_;
};
}  // namespace

std::vector<std::string> mesh_import_files(const std::string& path) {
  std::set<std::string> opened;
  try {
    (void)open_regular_file(path);  // a directory, a device: no import at all
    if (const std::string e = import_lower_ext(path);
        e != "gltf" && e != "glb" && e != "fbx" && e != "obj" && e != "pk3" && e != "bsp")
      import_check_collada(path);
    Assimp::Importer importer;
    import_keep_scene_readers(importer);
    importer.SetIOHandler(new RecordingIOSystem(opened));  // the importer owns and deletes it
    if (!importer.ReadFile(path, 0u)) return {};
  } catch (const std::exception&) {
    return {};
  }
  return {opened.begin(), opened.end()};
}

std::string mesh_loader_for(const SceneConfig& cfg) {
  if (cfg.mesh_loader == "obj" || cfg.mesh_loader == "assimp") return cfg.mesh_loader;
  if (cfg.mesh_loader != "auto")
    throw InputError("mesh_loader", "must be \"auto\", \"assimp\" or \"obj\", not \"" + cfg.mesh_loader + "\"");
  return import_lower_ext(cfg.file) == "obj" ? "obj" : "assimp";
}

MeshImportOptions mesh_import_options(const SceneConfig& cfg) {
  MeshImportOptions o;
  o.unit_m = cfg.mesh_unit_m;
  o.up = cfg.mesh_up;
  if (cfg.mesh_uv_set < 0) throw InputError("mesh_uv_set", "must be >= 0");
  o.uv_set = static_cast<unsigned>(cfg.mesh_uv_set);
  o.no_uv = cfg.mesh_no_uv;
  o.planar_m = cfg.mesh_planar_m;
  o.texels_per_m = cfg.texels_per_m;
  return o;
}

// The table's "mesh" (scene.cpp): cfg.file through the reader mesh_loader_for picks.
std::unique_ptr<IScene> make_file_mesh_scene(const SceneConfig& cfg, TextureExtent extent) {
  if (mesh_loader_for(cfg) == "obj") {
    ObjStats stats;
    auto scene = std::make_unique<MeshScene>(load_obj(cfg.file, &stats), extent);
    scene->set_load_warnings(obj_warnings(stats, cfg.file));
    return scene;
  }
  MeshImportStats stats;
  auto scene = std::make_unique<MeshScene>(
      import_mesh(cfg.file, mesh_import_options(cfg), extent.width, extent.height, &stats), extent);
  scene->set_load_warnings(mesh_import_warnings(stats, cfg.file));
  return scene;
}

}  // namespace vtsim
