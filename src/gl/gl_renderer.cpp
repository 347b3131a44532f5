#include "gl/gl_renderer.h"

#include <epoxy/gl.h>
#include <fmt/format.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include <glm/geometric.hpp>

#include "core/error.h"
#include "gl/gl_context.h"
#include "sim/view/mesh.h"
#include "sim/view/mesh_import.h"
#include "sim/view/scene_heightfield.h"
#include "sim/view/scene_town.h"

namespace vtsim::gl {

namespace {

// One vertex: position relative to the geometry's origin (float), texel coordinates relative to
// an integer texel origin of its chunk or triangle (float, so small: their differences, GL's
// derivatives, keep their precision anywhere in a 2^31-texel texture), and that origin.
struct Vertex {
  float p[3];
  float t[2];
  std::int32_t to[2];
};

constexpr std::int32_t kUntextured = INT_MIN;

struct Geometry {
  glm::dvec3 origin{0.0};
  std::vector<Vertex> verts;
  std::vector<std::uint32_t> idx;
};

Vertex make_vertex(const Geometry& g, const glm::dvec3& p, double tu, double tv, std::int64_t ou, std::int64_t ov) {
  Vertex v{};
  const glm::dvec3 r = p - g.origin;
  v.p[0] = static_cast<float>(r.x);
  v.p[1] = static_cast<float>(r.y);
  v.p[2] = static_cast<float>(r.z);
  v.t[0] = static_cast<float>(tu - static_cast<double>(ou));
  v.t[1] = static_cast<float>(tv - static_cast<double>(ov));
  v.to[0] = static_cast<std::int32_t>(ou);
  v.to[1] = static_cast<std::int32_t>(ov);
  return v;
}

// A grid of posts z(i, j) over the ground texture (plane and heightfield): chunks of `chunk`
// cells a side, each with its own vertices and texel origin; cells split along the (i, j)–
// (i+1, j+1) diagonal as HeightfieldScene intersects them: triangles (00, 10, 11), (00, 11, 01).
template <class Z>
void ground_grid(Geometry& g, int nx, int ny, double x0, double y0, double sx, double sy, const GroundTexture& tex, int chunk, Z z) {
  for (int cj = 0; cj < ny - 1; cj += chunk)
    for (int ci = 0; ci < nx - 1; ci += chunk) {
      const int ei = std::min(ci + chunk, nx - 1), ej = std::min(cj + chunk, ny - 1);
      const double tu0 = (x0 + ci * sx - tex.x0_m) * tex.texels_per_m, tv0 = (y0 + cj * sy - tex.y0_m) * tex.texels_per_m;
      const auto ou = static_cast<std::int64_t>(std::floor(tu0)), ov = static_cast<std::int64_t>(std::floor(tv0));
      const auto base = static_cast<std::uint32_t>(g.verts.size());
      const int w = ei - ci + 1;
      for (int j = cj; j <= ej; ++j)
        for (int i = ci; i <= ei; ++i) {
          const double x = x0 + i * sx, y = y0 + j * sy;
          g.verts.push_back(make_vertex(g, {x, y, z(i, j)}, (x - tex.x0_m) * tex.texels_per_m,
                                        (y - tex.y0_m) * tex.texels_per_m, ou, ov));
        }
      for (int j = cj; j < ej; ++j)
        for (int i = ci; i < ei; ++i) {
          const std::uint32_t a = base + static_cast<std::uint32_t>((j - cj) * w + (i - ci));
          const std::uint32_t b = a + 1, c = a + static_cast<std::uint32_t>(w), d = c + 1;
          g.idx.insert(g.idx.end(), {a, b, d, a, d, c});
        }
    }
}

Geometry build_geometry(const SceneConfig& cfg, TextureExtent& extent) {
  extent = scene_texture(cfg);
  Geometry g;
  const GroundTexture tex{cfg.origin_x_m, cfg.origin_y_m, cfg.texels_per_m, extent};
  if (cfg.kind == "plane") {
    // The texture's rectangle of the plane, as 64 m quads (the CPU plane is infinite, but a
    // sample outside the texture is no sample, as nothing drawn is).
    const double sx = static_cast<double>(extent.width) / cfg.texels_per_m, sy = static_cast<double>(extent.height) / cfg.texels_per_m;
    const double cell = 64.0;
    const int nx = static_cast<int>(std::ceil(sx / cell)) + 1, ny = static_cast<int>(std::ceil(sy / cell)) + 1;
    g.origin = {cfg.origin_x_m + 0.5 * sx, cfg.origin_y_m + 0.5 * sy, cfg.plane_z_m};
    // Posts evenly spaced, the last one at the texture's edge.
    ground_grid(g, nx, ny, cfg.origin_x_m, cfg.origin_y_m, sx / (nx - 1), sy / (ny - 1), tex, 1,
                [&](int, int) { return cfg.plane_z_m; });
    return g;
  }
  if (cfg.kind == "heightfield") {
    const auto scene = make_scene(cfg);
    const auto* hs = dynamic_cast<const HeightfieldScene*>(scene.get());
    if (hs == nullptr) throw std::logic_error("heightfield scene is not a HeightfieldScene");
    const Heightfield& hf = hs->heightfield();
    g.origin = {hf.x0_m + 0.5 * (hf.nx - 1) * hf.spacing_m, hf.y0_m + 0.5 * (hf.ny - 1) * hf.spacing_m, 0.0};
    ground_grid(g, hf.nx, hf.ny, hf.x0_m, hf.y0_m, hf.spacing_m, hf.spacing_m, tex, 16, [&](int i, int j) {
      return static_cast<double>(hf.z_m[static_cast<std::size_t>(j) * static_cast<std::size_t>(hf.nx) + static_cast<std::size_t>(i)]);
    });
    return g;
  }
  Mesh m;
  if (cfg.kind == "town") {
    m = generate_town(cfg);
  } else if (cfg.kind == "mesh") {
    m = mesh_loader_for(cfg) == "obj" ? load_obj(cfg.file)
                                      : import_mesh(cfg.file, mesh_import_options(cfg), extent.width, extent.height);
  } else {
    throw InputError("scene", fmt::format("the GL client draws plane, heightfield, town and mesh, not '{}'", cfg.kind));
  }
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (const auto& p : m.positions) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  g.origin = 0.5 * (lo + hi);
  const double W = static_cast<double>(extent.width), H = static_cast<double>(extent.height);
  for (const Mesh::Tri& t : m.tris) {
    double tu[3] = {0, 0, 0}, tv[3] = {0, 0, 0};
    std::int64_t ou = kUntextured, ov = 0;
    if (t.t[0] >= 0) {
      for (int k = 0; k < 3; ++k) {
        tu[k] = m.uvs[static_cast<std::size_t>(t.t[k])].x * W;
        tv[k] = m.uvs[static_cast<std::size_t>(t.t[k])].y * H;
      }
      ou = static_cast<std::int64_t>(std::floor(std::min({tu[0], tu[1], tu[2]})));
      ov = static_cast<std::int64_t>(std::floor(std::min({tv[0], tv[1], tv[2]})));
    }
    for (int k = 0; k < 3; ++k) {
      g.idx.push_back(static_cast<std::uint32_t>(g.verts.size()));
      Vertex v = make_vertex(g, m.positions[t.p[k]], tu[k], tv[k], ou == kUntextured ? 0 : ou, ov);
      if (ou == kUntextured) v.to[0] = kUntextured;
      g.verts.push_back(v);
    }
  }
  return g;
}

const char* kVertexShader = R"(#version 450 core
layout(location = 0) in vec3 a_p;
layout(location = 1) in vec2 a_t;
layout(location = 2) in ivec2 a_to;
uniform mat4 u_vp;     // camera rotation and projection (the camera at the origin)
uniform vec3 u_off;    // geometry origin - camera position, metres
out vec2 v_t;
flat out ivec2 v_to;
void main() {
  gl_Position = u_vp * vec4(a_p + u_off, 1.0);
  v_t = a_t;
  v_to = a_to;
}
)";

// Shared by both passes: GL's rho from the fine derivatives of the texel coordinates.
const char* kLodFunctions = R"(
uniform float u_bias;
uniform int u_aniso;
uniform float u_inv_aniso2;
uniform ivec2 u_extent;
float lod_of(vec2 t) {
  vec2 dx = dFdxFine(t), dy = dFdyFine(t);
  float lx2 = dot(dx, dx), ly2 = dot(dy, dy);
  float q = u_aniso == 0 ? max(lx2, ly2) : max(min(lx2, ly2), max(lx2, ly2) * u_inv_aniso2);
  return 0.5 * log2(max(q, 1e-36)) + u_bias;
}
)";

const char* kFeedbackFragment = R"(
in vec2 v_t;
flat in ivec2 v_to;
layout(location = 0) out uvec4 o;
void main() {
  float lod = lod_of(v_t);
  if (v_to.x == -2147483648) { o = uvec4(0u, 0u, 0u, 4u); return; }
  ivec2 ti = v_to + ivec2(floor(v_t));
  uint status = gl_FrontFacing ? 1u : 2u;
  if (status == 1u && (ti.x < 0 || ti.y < 0 || ti.x >= u_extent.x || ti.y >= u_extent.y)) status = 3u;
  o = uvec4(uint(ti.x), uint(ti.y), floatBitsToUint(lod), status);
}
)";

const char* kMainFragment = R"(
in vec2 v_t;
flat in ivec2 v_to;
layout(location = 0) out vec4 o;
uniform int u_levels;
const vec3 palette[12] = vec3[12](vec3(1,0,0), vec3(1,.5,0), vec3(1,1,0), vec3(.6,1,0), vec3(0,.8,0), vec3(0,1,1),
  vec3(0,0,1), vec3(.5,0,1), vec3(1,0,1), vec3(1,.6,.8), vec3(.6,.3,0), vec3(1,1,1));
void main() {
  float lod = lod_of(v_t);
  if (v_to.x == -2147483648) { o = vec4(0.3, 0.3, 0.3, 1.0); return; }
  if (!gl_FrontFacing) { o = vec4(0.1, 0.1, 0.1, 1.0); return; }
  int level = clamp(int(floor(max(lod, 0.0))), 0, u_levels - 1);
  ivec2 ti = v_to + ivec2(floor(v_t));
  ivec2 tile = (ti >> level) >> 7;                 // 128-texel tiles of the desired level
  ivec2 texel8 = (ti >> level) >> 3;               // 8-texel cells: the texture's own detail
  float shade = ((tile.x + tile.y) & 1) == 0 ? 1.0 : 0.75;
  shade *= ((texel8.x + texel8.y) & 1) == 0 ? 1.0 : 0.9;
  o = vec4(palette[level % 12] * shade, 1.0);
}
)";

const char* kTexturedFragment = R"(
in vec2 v_t;
flat in ivec2 v_to;
layout(location = 0) out vec4 o;
layout(binding = 0) uniform sampler2D u_ref;
layout(binding = 1) uniform sampler2D u_phys;
layout(std430, binding = 0) readonly buffer PageTable { uint pt[]; };
uniform int u_vt, u_levels, u_min_level, u_tile, u_border, u_slots_x;
uniform int u_level_off[24];
uniform vec2 u_phys_size;
// Level l's tile under texel position t0 (level 0), its texel position at l, and l's size.
void at_level(vec2 t0, int l, out vec2 p, out ivec2 tile, out ivec2 tiles) {
  ivec2 size = max(u_extent >> l, ivec2(1));
  p = t0 / vec2(u_extent) * vec2(size);
  tiles = (size + u_tile - 1) / u_tile;
  tile = clamp(ivec2(floor(p)) / u_tile, ivec2(0), tiles - 1);
}
void main() {
  float lod = lod_of(v_t);
  if (v_to.x == -2147483648 || !gl_FrontFacing) { o = vec4(0.0, 0.0, 0.0, 1.0); return; }
  int L = clamp(int(floor(lod + 0.5)), u_min_level, u_levels - 1);
  vec2 t0 = vec2(v_to) + v_t;
  if (u_vt == 0) { o = textureLod(u_ref, t0 / vec2(u_extent), float(L)); return; }
  vec2 p; ivec2 tile, tiles;
  at_level(t0, L, p, tile, tiles);
  uint e = pt[u_level_off[L] + tile.y * tiles.x + tile.x];
  int lr = int((e >> 16u) & 0xffu), slot = int(e & 0xffffu);
  at_level(t0, lr, p, tile, tiles);
  int side = u_tile + 2 * u_border;
  vec2 phys = vec2((slot % u_slots_x) * side + u_border, (slot / u_slots_x) * side + u_border) + (p - vec2(tile * u_tile));
  o = textureLod(u_phys, phys / u_phys_size, 0.0);
}
)";

GLuint compile(GLenum type, const std::string& src) {
  const GLuint s = glCreateShader(type);
  const char* p = src.c_str();
  glShaderSource(s, 1, &p, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[4096];
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    throw std::runtime_error(std::string("gl: shader does not compile: ") + log);
  }
  return s;
}

GLuint link(const std::string& fragment_body) {
  const GLuint vs = compile(GL_VERTEX_SHADER, kVertexShader);
  const GLuint fs = compile(GL_FRAGMENT_SHADER, std::string("#version 450 core\n") + kLodFunctions + fragment_body);
  const GLuint p = glCreateProgram();
  glAttachShader(p, vs);
  glAttachShader(p, fs);
  glLinkProgram(p);
  glDeleteShader(vs);
  glDeleteShader(fs);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[4096];
    glGetProgramInfoLog(p, sizeof log, nullptr, log);
    throw std::runtime_error(std::string("gl: program does not link: ") + log);
  }
  return p;
}

// Row-major 4×4 → column-major float for glUniformMatrix4fv.
struct Mat4 {
  double m[4][4] = {};
};

// The camera's view-projection with the camera at the origin: view space x right (−left), y up,
// z backwards (−fwd); an off-centre perspective for an image W×H with principal point (cx, cy),
// image rows growing downwards = window rows growing upwards flipped (so window row = image row,
// and GL's 2×2 quads pair the same feedback pixels as the model: rows 2k, 2k+1 from the top);
// reversed Z in [0, 1] (glClipControl) for depth precision from near to far.
Mat4 view_proj(const Camera& cam, double W, double H, double cx, double cy, double near_m, double far_m) {
  const glm::dvec3 right = -cam.left, up = cam.up, back = -cam.fwd;
  const double f = cam.focal_px;
  // clip = P · (X, Y, Z, 1) with view coordinates X = right·r, Y = up·r, Z = back·r.
  double P[4][4] = {};
  P[0][0] = 2.0 * f / W;
  P[0][2] = -(2.0 * cx / W - 1.0);
  P[1][1] = -2.0 * f / H;
  P[1][2] = -(2.0 * cy / H - 1.0);
  // Reversed Z: depth = near/(−Z) at far = ∞ … with a finite far: depth 1 at near, 0 at far.
  const double A = near_m / (far_m - near_m), B = far_m * near_m / (far_m - near_m);
  P[2][2] = A;
  P[2][3] = B;
  P[3][2] = -1.0;
  Mat4 r;
  const glm::dvec3 rows[3] = {right, up, back};
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 3; ++j) {
      double s = 0.0;
      for (int k = 0; k < 3; ++k) s += P[i][k] * rows[k][j];
      r.m[i][j] = s;
    }
  for (int i = 0; i < 4; ++i) r.m[i][3] = P[i][3];
  return r;
}

void set_mat(GLuint prog, const char* name, const Mat4& m) {
  float c[16];
  for (int col = 0; col < 4; ++col)
    for (int row = 0; row < 4; ++row) c[col * 4 + row] = static_cast<float>(m.m[row][col]);
  glProgramUniformMatrix4fv(prog, glGetUniformLocation(prog, name), 1, GL_FALSE, c);
}

struct Target {
  GLuint fbo = 0, colour = 0, depth = 0;
  int w = 0, h = 0;
  void make(int width, int height, GLenum format) {
    if (w == width && h == height && fbo != 0) return;
    release();
    w = width;
    h = height;
    glCreateFramebuffers(1, &fbo);
    glCreateRenderbuffers(1, &colour);
    glNamedRenderbufferStorage(colour, format, w, h);
    glCreateRenderbuffers(1, &depth);
    glNamedRenderbufferStorage(depth, GL_DEPTH_COMPONENT32F, w, h);
    glNamedFramebufferRenderbuffer(fbo, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, colour);
    glNamedFramebufferRenderbuffer(fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
    if (glCheckNamedFramebufferStatus(fbo, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("gl: framebuffer incomplete");
  }
  void release() {
    if (fbo) glDeleteFramebuffers(1, &fbo);
    if (colour) glDeleteRenderbuffers(1, &colour);
    if (depth) glDeleteRenderbuffers(1, &depth);
    fbo = colour = depth = 0;
  }
};

struct Pending {
  GLuint pbo = 0;
  GLsync fence = nullptr;
  long long frame = -1;
  int w = 0, h = 0;
};

}  // namespace

struct Renderer::Impl {
  GLuint vao = 0, vbo = 0, ibo = 0;
  GLsizei count = 0;
  glm::dvec3 origin{0.0};
  GLuint main_prog = 0, fb_prog = 0;
  Target main, fb;
  int levels = 1;
  std::deque<Pending> pending;
  std::vector<GLuint> free_pbos;
  // draw_textured's resources, made on first use.
  GLuint tex_prog = 0, ref_tex = 0, phys_tex = 0, pt_buf = 0;
  int vt_missing = -2;
  std::vector<std::vector<std::uint8_t>> mips;  // level l: RGBA8, max(W >> l, 1) × max(H >> l, 1)
  std::vector<int> level_off;                   // page-table offset of each level
  int slots_x = 0;

  void uniforms(GLuint prog, const Camera& cam, const FeedbackSettings& fs, double W, double H, double cx, double cy,
                float bias, TextureExtent ext) {
    set_mat(prog, "u_vp", view_proj(cam, W, H, cx, cy, fs.near_m, fs.far_m));
    const glm::dvec3 off = origin - cam.pos_m;
    glProgramUniform3f(prog, glGetUniformLocation(prog, "u_off"), static_cast<float>(off.x), static_cast<float>(off.y),
                       static_cast<float>(off.z));
    glProgramUniform1f(prog, glGetUniformLocation(prog, "u_bias"), bias);
    glProgramUniform1i(prog, glGetUniformLocation(prog, "u_aniso"), fs.anisotropic ? 1 : 0);
    glProgramUniform1f(prog, glGetUniformLocation(prog, "u_inv_aniso2"), 1.0f / (fs.max_aniso * fs.max_aniso));
    glProgramUniform2i(prog, glGetUniformLocation(prog, "u_extent"), static_cast<GLint>(std::min<std::int64_t>(ext.width, INT_MAX)),
                       static_cast<GLint>(std::min<std::int64_t>(ext.height, INT_MAX)));
  }
  void draw(GLuint prog, const Target& t) {
    glBindFramebuffer(GL_FRAMEBUFFER, t.fbo);
    glViewport(0, 0, t.w, t.h);
    glUseProgram(prog);
    glBindVertexArray(vao);
    glDrawElements(GL_TRIANGLES, count, GL_UNSIGNED_INT, nullptr);
  }
};

Renderer::Renderer(Context& ctx, const SceneConfig& cfg) : impl_(std::make_unique<Impl>()) {
  (void)ctx;
  Geometry g = build_geometry(cfg, extent_);
  if (g.idx.size() > static_cast<std::size_t>(INT_MAX)) throw InputError("gl", "the scene has too many triangles for one draw");
  triangles_ = g.idx.size() / 3;
  Impl& m = *impl_;
  m.origin = g.origin;
  m.levels = mip_level_count(extent_);
  m.count = static_cast<GLsizei>(g.idx.size());
  glCreateBuffers(1, &m.vbo);
  glNamedBufferStorage(m.vbo, static_cast<GLsizeiptr>(g.verts.size() * sizeof(Vertex)), g.verts.data(), 0);
  glCreateBuffers(1, &m.ibo);
  glNamedBufferStorage(m.ibo, static_cast<GLsizeiptr>(g.idx.size() * sizeof(std::uint32_t)), g.idx.data(), 0);
  glCreateVertexArrays(1, &m.vao);
  glVertexArrayVertexBuffer(m.vao, 0, m.vbo, 0, sizeof(Vertex));
  glVertexArrayElementBuffer(m.vao, m.ibo);
  glEnableVertexArrayAttrib(m.vao, 0);
  glVertexArrayAttribFormat(m.vao, 0, 3, GL_FLOAT, GL_FALSE, offsetof(Vertex, p));
  glVertexArrayAttribBinding(m.vao, 0, 0);
  glEnableVertexArrayAttrib(m.vao, 1);
  glVertexArrayAttribFormat(m.vao, 1, 2, GL_FLOAT, GL_FALSE, offsetof(Vertex, t));
  glVertexArrayAttribBinding(m.vao, 1, 0);
  glEnableVertexArrayAttrib(m.vao, 2);
  glVertexArrayAttribIFormat(m.vao, 2, 2, GL_INT, offsetof(Vertex, to));
  glVertexArrayAttribBinding(m.vao, 2, 0);
  m.main_prog = link(kMainFragment);
  m.fb_prog = link(kFeedbackFragment);
  glProgramUniform1i(m.main_prog, glGetUniformLocation(m.main_prog, "u_levels"), m.levels);
  glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_GREATER);  // reversed Z
  glDisable(GL_CULL_FACE);  // back faces occlude (and are never sampled), as in the CPU view
  // The projection flips y (window row = image row), which turns counter-clockwise faces clockwise.
  glFrontFace(GL_CW);
}

Renderer::~Renderer() {
  Impl& m = *impl_;
  for (Pending& p : m.pending) {
    glDeleteSync(p.fence);
    m.free_pbos.push_back(p.pbo);
  }
  for (GLuint b : m.free_pbos) glDeleteBuffers(1, &b);
  m.main.release();
  m.fb.release();
  glDeleteProgram(m.main_prog);
  if (m.tex_prog) glDeleteProgram(m.tex_prog);
  if (m.ref_tex) glDeleteTextures(1, &m.ref_tex);
  if (m.phys_tex) glDeleteTextures(1, &m.phys_tex);
  if (m.pt_buf) glDeleteBuffers(1, &m.pt_buf);
  glDeleteProgram(m.fb_prog);
  glDeleteVertexArrays(1, &m.vao);
  glDeleteBuffers(1, &m.vbo);
  glDeleteBuffers(1, &m.ibo);
}

void Renderer::draw_main(const Camera& cam, const FeedbackSettings& fs) {
  Impl& m = *impl_;
  m.main.make(cam.width, cam.height, GL_RGBA8);
  m.uniforms(m.main_prog, cam, fs, cam.width, cam.height, cam.cx, cam.cy, fs.lod_bias, extent_);
  glBindFramebuffer(GL_FRAMEBUFFER, m.main.fbo);
  const float sky[4] = {0.55f, 0.7f, 0.9f, 1.0f};
  const float zero = 0.0f;
  glClearNamedFramebufferfv(m.main.fbo, GL_COLOR, 0, sky);
  glClearNamedFramebufferfv(m.main.fbo, GL_DEPTH, 0, &zero);
  m.draw(m.main_prog, m.main);
}

namespace {

constexpr int kVtTile = 64, kVtBorder = 4;

// A procedural RGBA8 image with detail at every scale (per-texel hash noise over smooth bands),
// and its box-filtered mip chain.
std::vector<std::vector<std::uint8_t>> make_mips(int w, int h) {
  std::vector<std::vector<std::uint8_t>> mips;
  std::vector<std::uint8_t> l0(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 4);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      std::uint32_t k = static_cast<std::uint32_t>(x) * 73856093u ^ static_cast<std::uint32_t>(y) * 19349663u;
      k ^= k >> 13;
      k *= 0x5bd1e995u;
      k ^= k >> 15;
      std::uint8_t* p = &l0[(static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)) * 4];
      p[0] = static_cast<std::uint8_t>((k & 63u) + static_cast<std::uint32_t>(128 + 127 * std::sin(x * 0.05)) / 2);
      p[1] = static_cast<std::uint8_t>(((k >> 8) & 63u) + static_cast<std::uint32_t>((x ^ y) & 0x7f));
      p[2] = static_cast<std::uint8_t>(((k >> 16) & 127u) + static_cast<std::uint32_t>(((x >> 5) + (y >> 5)) & 1) * 100u);
      p[3] = 255;
    }
  mips.push_back(std::move(l0));
  int cw = w, ch = h;
  while (cw > 1 || ch > 1) {
    const int nw = std::max(cw / 2, 1), nh = std::max(ch / 2, 1);
    const std::vector<std::uint8_t>& src = mips.back();
    std::vector<std::uint8_t> dst(static_cast<std::size_t>(nw) * static_cast<std::size_t>(nh) * 4);
    for (int y = 0; y < nh; ++y)
      for (int x = 0; x < nw; ++x)
        for (int c = 0; c < 4; ++c) {
          int sum = 0;
          for (int dy = 0; dy < 2; ++dy)
            for (int dx = 0; dx < 2; ++dx) {
              const int sx = std::min(2 * x + dx, cw - 1), sy = std::min(2 * y + dy, ch - 1);
              sum += src[(static_cast<std::size_t>(sy) * static_cast<std::size_t>(cw) + static_cast<std::size_t>(sx)) * 4 +
                         static_cast<std::size_t>(c)];
            }
          dst[(static_cast<std::size_t>(y) * static_cast<std::size_t>(nw) + static_cast<std::size_t>(x)) * 4 +
              static_cast<std::size_t>(c)] = static_cast<std::uint8_t>((sum + 2) / 4);
        }
    mips.push_back(std::move(dst));
    cw = nw;
    ch = nh;
  }
  return mips;
}

}  // namespace

void Renderer::draw_textured(const Camera& cam, const FeedbackSettings& fs, bool virtual_texture, int min_level,
                             int missing_level) {
  Impl& m = *impl_;
  const int W = static_cast<int>(std::min<std::int64_t>(extent_.width, INT_MAX)),
            H = static_cast<int>(std::min<std::int64_t>(extent_.height, INT_MAX));
  if (extent_.width > 4096 || extent_.height > 4096)
    throw InputError("gl", fmt::format("draw_textured: the texture is {}x{} texels, at most 4096x4096 here", extent_.width,
                                       extent_.height));
  const int levels = m.levels;
  if (m.tex_prog == 0) {
    m.tex_prog = link(kTexturedFragment);
    m.mips = make_mips(W, H);
    glCreateTextures(GL_TEXTURE_2D, 1, &m.ref_tex);
    glTextureStorage2D(m.ref_tex, levels, GL_RGBA8, W, H);
    for (int l = 0; l < levels; ++l)
      glTextureSubImage2D(m.ref_tex, l, 0, 0, std::max(W >> l, 1), std::max(H >> l, 1), GL_RGBA, GL_UNSIGNED_BYTE,
                          m.mips[static_cast<std::size_t>(l)].data());
    glTextureParameteri(m.ref_tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_NEAREST);
    glTextureParameteri(m.ref_tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTextureParameteri(m.ref_tex, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTextureParameteri(m.ref_tex, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    // The physical page cache: every tile of every level in its slot, with borders copied from
    // the level's neighbouring texels (clamped at the level's edge, as the plain texture is).
    int total = 0;
    for (int l = 0; l < levels; ++l) {
      m.level_off.push_back(total);
      total += ((std::max(W >> l, 1) + kVtTile - 1) / kVtTile) * ((std::max(H >> l, 1) + kVtTile - 1) / kVtTile);
    }
    if (total > 0xffff) throw InputError("gl", "draw_textured: more than 65535 pages");
    m.slots_x = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(total))));
    const int side = kVtTile + 2 * kVtBorder, phys = m.slots_x * side;
    glCreateTextures(GL_TEXTURE_2D, 1, &m.phys_tex);
    glTextureStorage2D(m.phys_tex, 1, GL_RGBA8, phys, phys);
    glTextureParameteri(m.phys_tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTextureParameteri(m.phys_tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTextureParameteri(m.phys_tex, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTextureParameteri(m.phys_tex, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    std::vector<std::uint8_t> page(static_cast<std::size_t>(side) * side * 4);
    int slot = 0;
    for (int l = 0; l < levels; ++l) {
      const int lw = std::max(W >> l, 1), lh = std::max(H >> l, 1);
      const std::vector<std::uint8_t>& src = m.mips[static_cast<std::size_t>(l)];
      for (int ty = 0; ty < (lh + kVtTile - 1) / kVtTile; ++ty)
        for (int tx = 0; tx < (lw + kVtTile - 1) / kVtTile; ++tx, ++slot) {
          for (int y = 0; y < side; ++y)
            for (int x = 0; x < side; ++x) {
              const int sx = std::clamp(tx * kVtTile - kVtBorder + x, 0, lw - 1);
              const int sy = std::clamp(ty * kVtTile - kVtBorder + y, 0, lh - 1);
              std::memcpy(&page[(static_cast<std::size_t>(y) * side + static_cast<std::size_t>(x)) * 4],
                          &src[(static_cast<std::size_t>(sy) * static_cast<std::size_t>(lw) + static_cast<std::size_t>(sx)) * 4], 4);
            }
          glTextureSubImage2D(m.phys_tex, 0, (slot % m.slots_x) * side, (slot / m.slots_x) * side, side, side, GL_RGBA,
                              GL_UNSIGNED_BYTE, page.data());
        }
    }
    glCreateBuffers(1, &m.pt_buf);
    glNamedBufferData(m.pt_buf, static_cast<GLsizeiptr>(static_cast<std::size_t>(total) * 4), nullptr, GL_DYNAMIC_DRAW);
  }
  if (m.vt_missing != missing_level) {
    // The page table: each page its own slot and level, those of the missing level their
    // parent's entry (the finest resident ancestor).
    std::vector<std::uint32_t> pt;
    for (int l = 0; l < levels; ++l) {
      const int tw = (std::max(W >> l, 1) + kVtTile - 1) / kVtTile, th = (std::max(H >> l, 1) + kVtTile - 1) / kVtTile;
      for (int ty = 0; ty < th; ++ty)
        for (int tx = 0; tx < tw; ++tx)
          pt.push_back(static_cast<std::uint32_t>(pt.size()) | static_cast<std::uint32_t>(l) << 16);
    }
    for (int l = levels - 2; l >= 0; --l) {
      if (l != missing_level) continue;
      const int tw = (std::max(W >> l, 1) + kVtTile - 1) / kVtTile, th = (std::max(H >> l, 1) + kVtTile - 1) / kVtTile;
      const int pw = (std::max(W >> (l + 1), 1) + kVtTile - 1) / kVtTile, ph = (std::max(H >> (l + 1), 1) + kVtTile - 1) / kVtTile;
      for (int ty = 0; ty < th; ++ty)
        for (int tx = 0; tx < tw; ++tx)
          pt[static_cast<std::size_t>(m.level_off[static_cast<std::size_t>(l)] + ty * tw + tx)] =
              pt[static_cast<std::size_t>(m.level_off[static_cast<std::size_t>(l + 1)] + std::min(ty / 2, ph - 1) * pw +
                                          std::min(tx / 2, pw - 1))];
    }
    glNamedBufferSubData(m.pt_buf, 0, static_cast<GLsizeiptr>(pt.size() * 4), pt.data());
    m.vt_missing = missing_level;
  }
  m.main.make(cam.width, cam.height, GL_RGBA8);
  m.uniforms(m.tex_prog, cam, fs, cam.width, cam.height, cam.cx, cam.cy, fs.lod_bias, extent_);
  const GLuint p = m.tex_prog;
  glProgramUniform1i(p, glGetUniformLocation(p, "u_vt"), virtual_texture ? 1 : 0);
  glProgramUniform1i(p, glGetUniformLocation(p, "u_levels"), levels);
  glProgramUniform1i(p, glGetUniformLocation(p, "u_min_level"), std::clamp(min_level, 0, levels - 1));
  glProgramUniform1i(p, glGetUniformLocation(p, "u_tile"), kVtTile);
  glProgramUniform1i(p, glGetUniformLocation(p, "u_border"), kVtBorder);
  glProgramUniform1i(p, glGetUniformLocation(p, "u_slots_x"), m.slots_x);
  glProgramUniform1iv(p, glGetUniformLocation(p, "u_level_off"), static_cast<GLsizei>(std::min<std::size_t>(m.level_off.size(), 24)),
                      m.level_off.data());
  const float ps = static_cast<float>(m.slots_x * (kVtTile + 2 * kVtBorder));
  glProgramUniform2f(p, glGetUniformLocation(p, "u_phys_size"), ps, ps);
  glBindTextureUnit(0, m.ref_tex);
  glBindTextureUnit(1, m.phys_tex);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, m.pt_buf);
  const float sky[4] = {0.55f, 0.7f, 0.9f, 1.0f};
  const float zero = 0.0f;
  glClearNamedFramebufferfv(m.main.fbo, GL_COLOR, 0, sky);
  glClearNamedFramebufferfv(m.main.fbo, GL_DEPTH, 0, &zero);
  m.draw(p, m.main);
}

std::vector<std::uint8_t> Renderer::read_main(int& w, int& h) {
  Impl& m = *impl_;
  w = m.main.w;
  h = m.main.h;
  std::vector<std::uint8_t> px(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 4);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, m.main.fbo);
  glBindBuffer(GL_PIXEL_PACK_BUFFER, 0);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, px.data());  // window row = image row
  return px;
}

bool Renderer::feedback(const Camera& cam, const FeedbackSettings& fs, int ox, int oy, long long frame, FeedbackFrame& out) {
  Impl& m = *impl_;
  const int d = fs.divisor;
  if (d < 1 || ox < 0 || oy < 0 || ox >= d || oy >= d) throw std::invalid_argument("gl feedback: bad divisor or tile offset");
  const int bw = buffer_extent(cam.width, d), bh = buffer_extent(cam.height, d);
  m.fb.make(bw, bh, GL_RGBA32UI);
  // Feedback pixel centre b + 0.5 ↦ full-resolution position b·d + o + 0.5: an image of
  // (d·bw) × (d·bh) pixels with the principal point moved by −(o + 0.5 − d/2).
  const double sx = ox + 0.5 - 0.5 * d, sy = oy + 0.5 - 0.5 * d;
  const float bias = fs.lod_bias - static_cast<float>(std::log2(static_cast<double>(d)));
  m.uniforms(m.fb_prog, cam, fs, static_cast<double>(d) * bw, static_cast<double>(d) * bh, cam.cx - sx, cam.cy - sy, bias,
             extent_);
  const GLuint zero4[4] = {0, 0, 0, 0};
  const float zero = 0.0f;
  glClearNamedFramebufferuiv(m.fb.fbo, GL_COLOR, 0, zero4);
  glClearNamedFramebufferfv(m.fb.fbo, GL_DEPTH, 0, &zero);
  m.draw(m.fb_prog, m.fb);
  // Asynchronous readback: into a pixel-pack buffer, a fence behind it.
  Pending p;
  const auto bytes = static_cast<GLsizeiptr>(static_cast<std::size_t>(bw) * static_cast<std::size_t>(bh) * sizeof(FeedbackTexel));
  if (!m.free_pbos.empty()) {
    p.pbo = m.free_pbos.back();
    m.free_pbos.pop_back();
    GLint64 size = 0;
    glGetNamedBufferParameteri64v(p.pbo, GL_BUFFER_SIZE, &size);
    if (size != bytes) glNamedBufferData(p.pbo, bytes, nullptr, GL_STREAM_READ);
  } else {
    glCreateBuffers(1, &p.pbo);
    glNamedBufferData(p.pbo, bytes, nullptr, GL_STREAM_READ);
  }
  glBindFramebuffer(GL_READ_FRAMEBUFFER, m.fb.fbo);
  glBindBuffer(GL_PIXEL_PACK_BUFFER, p.pbo);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glReadPixels(0, 0, bw, bh, GL_RGBA_INTEGER, GL_UNSIGNED_INT, nullptr);
  glBindBuffer(GL_PIXEL_PACK_BUFFER, 0);
  p.fence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
  glFlush();
  p.frame = frame;
  p.w = bw;
  p.h = bh;
  m.pending.push_back(p);
  if (static_cast<int>(m.pending.size()) <= fs.latency) return false;
  return drain(out);
}

bool Renderer::drain(FeedbackFrame& out) {
  Impl& m = *impl_;
  if (m.pending.empty()) return false;
  Pending p = m.pending.front();
  m.pending.pop_front();
  while (glClientWaitSync(p.fence, GL_SYNC_FLUSH_COMMANDS_BIT, 1'000'000'000) == GL_TIMEOUT_EXPIRED) {
  }
  glDeleteSync(p.fence);
  out.frame = p.frame;
  out.width = p.w;
  out.height = p.h;
  out.px.resize(static_cast<std::size_t>(p.w) * static_cast<std::size_t>(p.h));
  glGetNamedBufferSubData(p.pbo, 0, static_cast<GLsizeiptr>(out.px.size() * sizeof(FeedbackTexel)), out.px.data());
  m.free_pbos.push_back(p.pbo);
  return true;
}

unsigned Renderer::link_program(const std::string& fragment_body) { return link(fragment_body); }

void Renderer::draw_program(unsigned program, const Camera& cam, const FeedbackSettings& fs) {
  Impl& m = *impl_;
  m.uniforms(program, cam, fs, cam.width, cam.height, cam.cx, cam.cy, fs.lod_bias, extent_);
  glViewport(0, 0, cam.width, cam.height);
  glUseProgram(program);
  glBindVertexArray(m.vao);
  glDrawElements(GL_TRIANGLES, m.count, GL_UNSIGNED_INT, nullptr);
}

FeedbackFrame Renderer::feedback_now(const Camera& cam, const FeedbackSettings& fs, int ox, int oy) {
  FeedbackSettings f = fs;
  f.latency = 0;
  FeedbackFrame out;
  while (drain(out)) {
  }
  feedback(cam, f, ox, oy, 0, out);
  return out;
}

}  // namespace vtsim::gl
