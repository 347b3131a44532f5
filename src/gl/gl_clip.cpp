#include "gl/gl_clip.h"

#include <epoxy/gl.h>
#include <fmt/format.h>

#include <algorithm>
#include <climits>
#include <stdexcept>
#include <string>

#include "core/error.h"

namespace vtsim::gl {

namespace {

constexpr int kMaxLevels = 32;

// Clipmap::resident_level on the GPU (cache/clipmap.h): the finest level l >= max(desired, clamp)
// whose footprint lies in its valid rectangle and in slots that hold their tiles in every layer.
const char* kClipFragment = R"(
in vec2 v_t;
flat in ivec2 v_to;
layout(location = 0) out vec4 o;
layout(location = 1) out uvec2 o_lv;   // (desired level + 1, sampled level + 1); 0: no sample
layout(binding = 1) uniform sampler2DArray u_stack;
layout(std430, binding = 0) readonly buffer Slots { uint slot_ok[]; };
uniform int u_levels, u_clamp, u_tile, u_margin;
uniform uint u_nonempty;    // bit l: level l has a valid slot
uniform ivec4 u_win[32];    // window origin and size, tiles of the level
uniform ivec4 u_valid[32];  // texels that may be sampled: [x0, x1) x [y0, y1) as (x0, x1, y0, y1)
uniform ivec4 u_size[32];   // level texels (x, y), the level's first slot in slot_ok, 0 no / 1 some / 2 every slot valid
bool usable(int l, ivec2 ti) {
  ivec4 sz = u_size[l];
  ivec2 c = ti >> l;
  ivec4 va = u_valid[l], w = u_win[l];
  int x0 = max(0, c.x - u_margin), x1 = min(sz.x - 1, c.x + u_margin);
  int y0 = max(0, c.y - u_margin), y1 = min(sz.y - 1, c.y + u_margin);
  if (x0 < va.x || x1 >= va.y || y0 < va.z || y1 >= va.w) return false;
  if (sz.w == 2) return true;  // complete (Clipmap::resident_level's missing == 0)
  for (int ty = y0 / u_tile; ty <= y1 / u_tile; ++ty)
    for (int tx = x0 / u_tile; tx <= x1 / u_tile; ++tx)
      if (slot_ok[sz.z + (ty % w.w) * w.z + (tx % w.z)] == 0u) return false;
  return true;
}
vec4 texel(int l, ivec2 c) {  // clamp addressing at the level's edges, toroidal in the layer
  ivec4 sz = u_size[l], w = u_win[l];
  c = clamp(c, ivec2(0), sz.xy - 1);
  return texelFetch(u_stack, ivec3(c.x % (w.z * u_tile), c.y % (w.w * u_tile), l), 0);
}
void main() {
  float lod = lod_of(v_t);
  o_lv = uvec2(0u);
  if (v_to.x == -2147483648) { o = vec4(0.3, 0.3, 0.3, 1.0); return; }
  if (!gl_FrontFacing) { o = vec4(0.1, 0.1, 0.1, 1.0); return; }
  ivec2 ti = v_to + ivec2(floor(v_t));
  if (ti.x < 0 || ti.y < 0 || ti.x >= u_extent.x || ti.y >= u_extent.y) { o = vec4(0.0, 0.0, 0.0, 1.0); return; }
  // The feedback's rule (desired_level): floor of the LOD, in [0, levels - 1].
  int desired = lod > 0.0 ? min(int(lod), u_levels - 1) : 0;
  int L = u_levels;
  // The levels from max(desired, clamp) down, finest first, skipping those with nothing valid.
  uint todo = u_nonempty & ~((1u << uint(max(desired, u_clamp))) - 1u);
  while (todo != 0u) {
    int l = findLSB(todo);
    if (usable(l, ti)) { L = l; break; }
    todo &= todo - 1u;
  }
  o_lv = uvec2(uint(desired + 1), uint(L + 1));
  if (L == u_levels) { o = vec4(0.5, 0.5, 0.5, 1.0); return; }
  // Bilinear at level L around its texel b = ti >> L, the offset within b kept exact (the level-0
  // texel's remainder and the fragment's fraction) so texture coordinates far out lose nothing.
  ivec2 b = ti >> L;
  vec2 p = (vec2(ti - (b << L)) + fract(v_t)) / exp2(float(L)) - 0.5;
  ivec2 i0 = b + ivec2(floor(p));
  vec2 f = p - floor(p);
  vec4 c = mix(mix(texel(L, i0), texel(L, i0 + ivec2(1, 0)), f.x), mix(texel(L, i0 + ivec2(0, 1)), texel(L, i0 + ivec2(1, 1)), f.x), f.y);
  o = vec4(c.rgb, 1.0);
}
)";

}  // namespace

struct StreamedClip::Impl {
  GLuint prog = 0, stack = 0, slots = 0;
  int side = 0;  // T + 2B: a stored tile's side
  std::size_t tile_bytes = 0;
  std::vector<std::uint32_t> ok;  // slot validity, levels' slots in order
  std::unique_ptr<StreamPass> pass;
};

StreamedClip::StreamedClip(Renderer& r, const ClipGeometry& g) : impl_(std::make_unique<Impl>()), r_(r), g_(g) {
  if (g.tile < 1 || g.border < 0 || g.channels < 1 || g.channels > 4 || g.layers < 1 || g.layers > 16 || g.filter_margin < 0 ||
      g.invalid_border < 0)
    throw InputError("gl", fmt::format("clip stack: bad tile geometry (tile {}, border {}, channels {}, layers {})", g.tile, g.border,
                                       g.channels, g.layers));
  if (g.clipsize < g.tile || g.clipsize % g.tile != 0)
    throw InputError("clipmap.clipsize", fmt::format("{} is not a positive multiple of the tile size {}", g.clipsize, g.tile));
  if (g.extent.width < 1 || g.extent.height < 1 || g.extent.width > (std::int64_t{1} << 30) || g.extent.height > (std::int64_t{1} << 30))
    throw InputError("texture.width", fmt::format("the GL clip stack addresses textures up to 2^30 texels a side, not {}x{}",
                                                  g.extent.width, g.extent.height));
  full_mask_ = (1u << g.layers) - 1u;
  // The levels and windows of cache/clipmap.h: down to 1×1; a level larger than N is the stack (a
  // window of N/T tiles a side, fewer along a shorter side), the rest the pyramid (whole).
  const std::int64_t n = g.clipsize / g.tile;
  std::int64_t w = g.extent.width, h = g.extent.height;
  int slot_off = 0;
  for (;;) {
    Level L;
    L.texels_x = w;
    L.texels_y = h;
    L.tiles_x = (w + g.tile - 1) / g.tile;
    L.tiles_y = (h + g.tile - 1) / g.tile;
    const bool stack = std::max(w, h) > g.clipsize;
    L.wx = stack ? std::min(n, L.tiles_x) : L.tiles_x;
    L.wy = stack ? std::min(n, L.tiles_y) : L.tiles_y;
    L.win = {0, 0, L.wx, L.wy};
    L.slot_off = slot_off;
    L.slots.resize(static_cast<std::size_t>(L.wx * L.wy));
    slot_off += static_cast<int>(L.wx * L.wy);
    lv_.push_back(std::move(L));
    if (w == 1 && h == 1) break;
    w = (w + 1) / 2;
    h = (h + 1) / 2;
  }
  if (levels() > kMaxLevels) throw InputError("texture.width", fmt::format("the GL clip stack draws up to {} levels, not {}", kMaxLevels, levels()));
  Impl& m = *impl_;
  GLint max_side = 0, max_layers = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_side);
  glGetIntegerv(GL_MAX_ARRAY_TEXTURE_LAYERS, &max_layers);
  // A layer holds the largest window: N×N, or less when the texture is smaller than the clipsize.
  for (const Level& L : lv_) {
    layer_w_ = std::max(layer_w_, static_cast<int>(L.wx * g.tile));
    layer_h_ = std::max(layer_h_, static_cast<int>(L.wy * g.tile));
  }
  const auto stack_bytes = static_cast<std::uint64_t>(layer_w_) * static_cast<std::uint64_t>(layer_h_) *
                           static_cast<std::uint64_t>(levels()) * static_cast<std::uint64_t>(g.channels);
  if (std::max(layer_w_, layer_h_) > max_side || levels() > max_layers || stack_bytes > (std::uint64_t{1} << 30))
    throw InputError("clipmap.clipsize", fmt::format("a clip stack of {} layers of {}x{} texels ({} MiB) exceeds this GL's {}² x {} "
                                                     "layers or the client's 1 GiB",
                                                     levels(), layer_w_, layer_h_, stack_bytes >> 20, max_side, max_layers));
  m.side = g.tile + 2 * g.border;
  m.tile_bytes = static_cast<std::size_t>(m.side) * static_cast<std::size_t>(m.side) * static_cast<std::size_t>(g.channels);
  glCreateTextures(GL_TEXTURE_2D_ARRAY, 1, &m.stack);
  glTextureStorage3D(m.stack, 1, gl_internal_format(g.channels), layer_w_, layer_h_, levels());
  glTextureParameteri(m.stack, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(m.stack, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  m.ok.assign(static_cast<std::size_t>(slot_off), 0u);
  glCreateBuffers(1, &m.slots);
  glNamedBufferData(m.slots, static_cast<GLsizeiptr>(m.ok.size() * 4), m.ok.data(), GL_DYNAMIC_DRAW);
  m.pass = std::make_unique<StreamPass>(m.tile_bytes);
  m.prog = Renderer::link_program(kClipFragment);
  const GLuint p = m.prog;
  glProgramUniform1i(p, glGetUniformLocation(p, "u_levels"), levels());
  glProgramUniform1i(p, glGetUniformLocation(p, "u_tile"), g.tile);
  glProgramUniform1i(p, glGetUniformLocation(p, "u_margin"), g.filter_margin);
}

StreamedClip::~StreamedClip() {
  Impl& m = *impl_;
  m.pass.reset();
  glDeleteTextures(1, &m.stack);
  glDeleteBuffers(1, &m.slots);
  glDeleteProgram(m.prog);
}

double StreamedClip::upload_gpu_ms() const { return impl_->pass->upload_gpu_ms(); }
std::uint64_t StreamedClip::timed_frames() const { return impl_->pass->timed_frames(); }

void StreamedClip::upload(const TileUpload& u) {
  ++uploads_;
  Impl& m = *impl_;
  const int l = static_cast<int>(u.key.level());
  if (l >= levels() || static_cast<int>(u.key.layer()) >= g_.layers)
    throw std::runtime_error(fmt::format("gl upload: tile (layer {}, level {}) outside the clip stack", u.key.layer(), l));
  Level& L = lv_[static_cast<std::size_t>(l)];
  const std::int64_t tx = u.key.x(), ty = u.key.y();
  if (tx < 0 || ty < 0 || tx >= L.tiles_x || ty >= L.tiles_y)
    throw std::runtime_error(fmt::format("gl upload: tile ({}, {}) outside level {} of {}x{} tiles", tx, ty, l, L.tiles_x, L.tiles_y));
  const std::int64_t sx = tx % L.wx, sy = ty % L.wy;  // the toroidal slot
  if (u.key.layer() == 0 && u.data != nullptr) {
    if (static_cast<int>(u.data->side) != m.side || static_cast<int>(u.data->channels) != g_.channels || u.data->bytes != m.tile_bytes)
      throw std::runtime_error(fmt::format("gl upload: tile {}x{}x{} where the clip stack holds {}x{}x{}", u.data->side, u.data->side,
                                           u.data->channels, m.side, m.side, g_.channels));
    // The payload: T×T texels inside the stored border, into the slot of layer l.
    m.pass->copy(u.data->texels.get(), m.tile_bytes, [&] {
      glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
      glPixelStorei(GL_UNPACK_ROW_LENGTH, m.side);
      glPixelStorei(GL_UNPACK_SKIP_PIXELS, g_.border);
      glPixelStorei(GL_UNPACK_SKIP_ROWS, g_.border);
      glTextureSubImage3D(m.stack, 0, static_cast<GLint>(sx) * g_.tile, static_cast<GLint>(sy) * g_.tile, l, g_.tile, g_.tile, 1,
                          gl_pixel_format(g_.channels), GL_UNSIGNED_BYTE, nullptr);
      glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
      glPixelStorei(GL_UNPACK_SKIP_PIXELS, 0);
      glPixelStorei(GL_UNPACK_SKIP_ROWS, 0);
    });
    ++copies_;
  }
  // The slot's residency, as Clipmap::commit keeps it: another tile overwrites the slot.
  Slot& s = L.slots[static_cast<std::size_t>(sy * L.wx + sx)];
  if (s.tx != tx || s.ty != ty) s = Slot{tx, ty, 0};
  s.mask |= 1u << u.key.layer();
  dirty_ = true;
}

void StreamedClip::apply(const FrameUpdates& u) {
  Impl& m = *impl_;
  m.pass->end_uploads();
  for (const FrameUpdates::Window& w : u.windows) {
    if (w.level < 0 || w.level >= levels()) throw std::logic_error(fmt::format("gl clip stack: a window for level {}", w.level));
    Level& L = lv_[static_cast<std::size_t>(w.level)];
    if (w.window.w != L.wx || w.window.h != L.wy)
      throw std::logic_error(fmt::format("gl clip stack: level {}'s window is {}x{} tiles, the stack's {}x{}", w.level, w.window.w,
                                         w.window.h, L.wx, L.wy));
    L.win = w.window;
    dirty_ = true;
  }
  if (!dirty_) return;
  std::vector<GLint> win, valid, size;
  std::uint32_t nonempty = 0;
  const std::int64_t T = g_.tile, b = g_.invalid_border;
  for (const Level& L : lv_) {
    const ClipWindow& W = L.win;
    win.insert(win.end(), {static_cast<GLint>(W.x0), static_cast<GLint>(W.y0), static_cast<GLint>(W.w), static_cast<GLint>(W.h)});
    // Clipmap::set_window: the invalid border lies along window edges that can move (not on the
    // texture's edge; a pyramid level's window is the whole level, so it has none).
    const std::int64_t tx0 = W.x0 + (W.x0 > 0 ? b : 0), tx1 = W.x0 + W.w - (W.x0 + W.w < L.tiles_x ? b : 0);
    const std::int64_t ty0 = W.y0 + (W.y0 > 0 ? b : 0), ty1 = W.y0 + W.h - (W.y0 + W.h < L.tiles_y ? b : 0);
    valid.insert(valid.end(), {static_cast<GLint>(tx0 * T), static_cast<GLint>(std::min(L.texels_x, tx1 * T)), static_cast<GLint>(ty0 * T),
                               static_cast<GLint>(std::min(L.texels_y, ty1 * T))});
    // A slot is valid when it holds, in every layer, the window tile that maps to it.
    std::size_t valid_slots = 0;
    for (std::size_t i = 0; i < L.slots.size(); ++i) {
      const Slot& s = L.slots[i];
      const bool in = s.tx >= W.x0 && s.tx < W.x0 + W.w && s.ty >= W.y0 && s.ty < W.y0 + W.h;
      const bool v = in && s.mask == full_mask_;
      m.ok[static_cast<std::size_t>(L.slot_off) + i] = v ? 1u : 0u;
      valid_slots += v ? 1 : 0;
    }
    const int state = valid_slots == 0 ? 0 : valid_slots == L.slots.size() ? 2 : 1;
    if (state != 0) nonempty |= 1u << (&L - lv_.data());
    size.insert(size.end(), {static_cast<GLint>(L.texels_x), static_cast<GLint>(L.texels_y), L.slot_off, state});
  }
  glProgramUniform4iv(m.prog, glGetUniformLocation(m.prog, "u_win"), levels(), win.data());
  glProgramUniform4iv(m.prog, glGetUniformLocation(m.prog, "u_valid"), levels(), valid.data());
  glProgramUniform4iv(m.prog, glGetUniformLocation(m.prog, "u_size"), levels(), size.data());
  glProgramUniform1ui(m.prog, glGetUniformLocation(m.prog, "u_nonempty"), nonempty);
  glNamedBufferSubData(m.slots, 0, static_cast<GLsizeiptr>(m.ok.size() * 4), m.ok.data());
  dirty_ = false;
}

PopinCount StreamedClip::draw(const Camera& cam, const FeedbackSettings& fs, int clamp, double /*sample_bias*/) {
  Impl& m = *impl_;
  glProgramUniform1i(m.prog, glGetUniformLocation(m.prog, "u_clamp"), std::clamp(clamp, 0, levels() - 1));
  glBindTextureUnit(1, m.stack);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, m.slots);
  return m.pass->draw(r_, m.prog, cam, fs);
}

std::vector<std::uint8_t> StreamedClip::read_colour(int& w, int& h) { return impl_->pass->read_colour(w, h); }

std::vector<ClipWindow> StreamedClip::gpu_windows() const {
  std::vector<ClipWindow> out;
  for (int l = 0; l < levels(); ++l) {
    GLint v[4] = {0, 0, 0, 0};
    glGetUniformiv(impl_->prog, glGetUniformLocation(impl_->prog, fmt::format("u_win[{}]", l).c_str()), v);
    out.push_back({v[0], v[1], v[2], v[3]});
  }
  return out;
}

bool StreamedClip::gpu_tile_valid(int level, std::int64_t tx, std::int64_t ty) const {
  const Level& L = lv_.at(static_cast<std::size_t>(level));
  const ClipWindow& W = L.win;
  if (tx < W.x0 || tx >= W.x0 + W.w || ty < W.y0 || ty >= W.y0 + W.h) return false;
  std::uint32_t v = 0;
  const auto i = static_cast<std::size_t>(L.slot_off) + static_cast<std::size_t>((ty % L.wy) * L.wx + tx % L.wx);
  glGetNamedBufferSubData(impl_->slots, static_cast<GLintptr>(i * 4), 4, &v);
  return v != 0;
}

}  // namespace vtsim::gl
