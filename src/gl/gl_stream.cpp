#include "gl/gl_stream.h"

#include <epoxy/gl.h>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstring>
#include <deque>
#include <stdexcept>

#include "core/error.h"
#include "core/view.h"

namespace vtsim::gl {

namespace {

const char* kStreamFragment = R"(
in vec2 v_t;
flat in ivec2 v_to;
layout(location = 0) out vec4 o;
layout(location = 1) out uvec2 o_lv;   // (desired level + 1, sampled level + 1); 0: no sample
layout(binding = 1) uniform sampler2D u_phys;
layout(std430, binding = 0) readonly buffer PageTable { uint pt[]; };
uniform int u_levels, u_clamp, u_tile, u_border, u_slots_x;
uniform int u_level_off[32];
uniform vec2 u_phys_size;
uniform float u_sample_bias;
void at_level(vec2 t0, int l, out vec2 p, out ivec2 tile, out ivec2 tiles) {
  ivec2 size = max(u_extent >> l, ivec2(1));
  p = t0 / vec2(u_extent) * vec2(size);
  tiles = (size + u_tile - 1) / u_tile;
  tile = clamp(ivec2(floor(p)) / u_tile, ivec2(0), tiles - 1);
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
  float ls = lod + u_sample_bias;
  int L = max(ls > 0.0 ? min(int(ls), u_levels - 1) : 0, u_clamp);
  vec2 t0 = vec2(v_to) + v_t;
  vec2 p; ivec2 tile, tiles;
  at_level(t0, L, p, tile, tiles);
  uint e = pt[u_level_off[L] + tile.y * tiles.x + tile.x];
  if (e == 0xffffffffu) { o = vec4(0.5, 0.5, 0.5, 1.0); o_lv = uvec2(uint(desired + 1), uint(u_levels + 1)); return; }
  int lr = int(e >> 24u), slot = int(e & 0xffffffu);
  at_level(t0, lr, p, tile, tiles);
  int side = u_tile + 2 * u_border;
  vec2 phys = vec2((slot % u_slots_x) * side + u_border, (slot / u_slots_x) * side + u_border) + (p - vec2(tile * u_tile));
  o = vec4(textureLod(u_phys, phys / u_phys_size, 0.0).rgb, 1.0);
  o_lv = uvec2(uint(desired + 1), uint(lr + 1));
}
)";

// Sums the per-pixel levels on the GPU: samples, blurry (sampled − desired ≥ 1), deficit.
const char* kCountCompute = R"(#version 450 core
layout(local_size_x = 16, local_size_y = 16) in;
layout(binding = 0, rg32ui) readonly uniform uimage2D u_lv;
layout(std430, binding = 1) buffer Counts { uint samples; uint blurry; uint deficit; };
void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (any(greaterThanEqual(p, imageSize(u_lv)))) return;
  uvec2 v = imageLoad(u_lv, p).xy;
  if (v.x == 0u) return;
  atomicAdd(samples, 1u);
  int d = int(v.y) - int(v.x);
  if (d >= 1) { atomicAdd(blurry, 1u); atomicAdd(deficit, uint(d)); }
}
)";

constexpr int kRing = 16;     // pixel-unpack buffers in the upload ring
constexpr int kQueries = 8;   // timer queries in flight

GLenum format_of(int channels) {
  switch (channels) {
    case 1: return GL_RED;
    case 2: return GL_RG;
    case 3: return GL_RGB;
    default: return GL_RGBA;
  }
}
GLenum internal_of(int channels) {
  switch (channels) {
    case 1: return GL_R8;
    case 2: return GL_RG8;
    case 3: return GL_RGB8;
    default: return GL_RGBA8;
  }
}

// Links the pop-in count's compute program (throws when it does not compile or link).
GLuint link_count_program() {
  const GLuint cs = glCreateShader(GL_COMPUTE_SHADER);
  glShaderSource(cs, 1, &kCountCompute, nullptr);
  glCompileShader(cs);
  GLint ok = 0;
  glGetShaderiv(cs, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[4096];
    glGetShaderInfoLog(cs, sizeof log, nullptr, log);
    glDeleteShader(cs);
    throw std::runtime_error(std::string("gl: the pop-in count shader does not compile: ") + log);
  }
  const GLuint prog = glCreateProgram();
  glAttachShader(prog, cs);
  glLinkProgram(prog);
  glDeleteShader(cs);
  glGetProgramiv(prog, GL_LINK_STATUS, &ok);
  if (!ok) {
    glDeleteProgram(prog);
    throw std::runtime_error("gl: the pop-in count program does not link");
  }
  return prog;
}

}  // namespace

unsigned gl_pixel_format(int channels) { return format_of(channels); }
unsigned gl_internal_format(int channels) { return internal_of(channels); }

struct StreamPass::Impl {
  GLuint count_prog = 0, counts = 0;
  GLuint fbo = 0, colour = 0, lv = 0, depth = 0;
  int w = 0, h = 0;
  std::size_t staging = 0;
  std::array<GLuint, kRing> pbo{};
  std::array<GLsync, kRing> fence{};
  int ring = 0;
  std::array<GLuint, kQueries> query{};
  std::deque<int> pending_queries;  // indices into query, oldest first
  int next_query = 0;
  bool query_open = false;

  void target(int nw, int nh) {
    if (fbo != 0 && nw == w && nh == h) return;
    if (fbo != 0) {
      glDeleteFramebuffers(1, &fbo);
      glDeleteTextures(1, &colour);
      glDeleteTextures(1, &lv);
      glDeleteTextures(1, &depth);
    }
    w = nw;
    h = nh;
    glCreateTextures(GL_TEXTURE_2D, 1, &colour);
    glTextureStorage2D(colour, 1, GL_RGBA8, w, h);
    glCreateTextures(GL_TEXTURE_2D, 1, &lv);
    glTextureStorage2D(lv, 1, GL_RG32UI, w, h);
    glCreateTextures(GL_TEXTURE_2D, 1, &depth);
    glTextureStorage2D(depth, 1, GL_DEPTH_COMPONENT32F, w, h);
    glCreateFramebuffers(1, &fbo);
    glNamedFramebufferTexture(fbo, GL_COLOR_ATTACHMENT0, colour, 0);
    glNamedFramebufferTexture(fbo, GL_COLOR_ATTACHMENT1, lv, 0);
    glNamedFramebufferTexture(fbo, GL_DEPTH_ATTACHMENT, depth, 0);
    const GLenum bufs[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    glNamedFramebufferDrawBuffers(fbo, 2, bufs);
    if (glCheckNamedFramebufferStatus(fbo, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("gl: the streamed main pass's framebuffer is incomplete");
  }
};

StreamPass::StreamPass(std::size_t staging_bytes) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.staging = staging_bytes;
  for (GLuint& b : m.pbo) {
    glCreateBuffers(1, &b);
    glNamedBufferStorage(b, static_cast<GLsizeiptr>(staging_bytes), nullptr, GL_MAP_WRITE_BIT);
  }
  glCreateQueries(GL_TIME_ELAPSED, kQueries, m.query.data());
  glCreateBuffers(1, &m.counts);
  glNamedBufferData(m.counts, 16, nullptr, GL_DYNAMIC_READ);
  m.count_prog = link_count_program();
}

StreamPass::~StreamPass() {
  Impl& m = *impl_;
  if (m.query_open) glEndQuery(GL_TIME_ELAPSED);
  for (GLsync& f : m.fence)
    if (f) glDeleteSync(f);
  glDeleteBuffers(kRing, m.pbo.data());
  glDeleteQueries(kQueries, m.query.data());
  if (m.fbo) {
    glDeleteFramebuffers(1, &m.fbo);
    glDeleteTextures(1, &m.colour);
    glDeleteTextures(1, &m.lv);
    glDeleteTextures(1, &m.depth);
  }
  glDeleteBuffers(1, &m.counts);
  glDeleteProgram(m.count_prog);
}

void StreamPass::copy(const void* bytes, std::size_t n, const std::function<void()>& copy) {
  Impl& m = *impl_;
  if (n > m.staging) throw std::logic_error("gl upload: a copy larger than the staging buffers");
  if (!m.query_open && m.pending_queries.size() < kQueries) {
    glBeginQuery(GL_TIME_ELAPSED, m.query[static_cast<std::size_t>(m.next_query)]);
    m.query_open = true;
  }
  // The ring's next buffer, once the GPU has read what it held.
  const auto i = static_cast<std::size_t>(m.ring);
  m.ring = (m.ring + 1) % kRing;
  if (m.fence[i]) {
    while (glClientWaitSync(m.fence[i], GL_SYNC_FLUSH_COMMANDS_BIT, 1'000'000'000) == GL_TIMEOUT_EXPIRED) {
    }
    glDeleteSync(m.fence[i]);
    m.fence[i] = nullptr;
  }
  void* dst = glMapNamedBufferRange(m.pbo[i], 0, static_cast<GLsizeiptr>(n),
                                    GL_MAP_WRITE_BIT | GL_MAP_INVALIDATE_BUFFER_BIT | GL_MAP_UNSYNCHRONIZED_BIT);
  if (dst == nullptr) throw std::runtime_error("gl upload: cannot map the staging buffer");
  std::memcpy(dst, bytes, n);
  glUnmapNamedBuffer(m.pbo[i]);
  glBindBuffer(GL_PIXEL_UNPACK_BUFFER, m.pbo[i]);
  copy();
  glBindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
  m.fence[i] = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
}

void StreamPass::end_uploads() {
  Impl& m = *impl_;
  if (m.query_open) {
    glEndQuery(GL_TIME_ELAPSED);
    m.query_open = false;
    m.pending_queries.push_back(m.next_query);
    m.next_query = (m.next_query + 1) % kQueries;
  }
  while (!m.pending_queries.empty()) {
    const GLuint q = m.query[static_cast<std::size_t>(m.pending_queries.front())];
    GLint ready = 0;
    glGetQueryObjectiv(q, GL_QUERY_RESULT_AVAILABLE, &ready);
    if (!ready) break;
    GLuint64 ns = 0;
    glGetQueryObjectui64v(q, GL_QUERY_RESULT, &ns);
    upload_gpu_ms_ += static_cast<double>(ns) * 1e-6;
    ++timed_frames_;
    m.pending_queries.pop_front();
  }
}

PopinCount StreamPass::draw(Renderer& r, unsigned program, const Camera& cam, const FeedbackSettings& fs) {
  Impl& m = *impl_;
  m.target(cam.width, cam.height);
  const float sky[4] = {0.55f, 0.7f, 0.9f, 1.0f};
  const GLuint zero4[4] = {0, 0, 0, 0};
  const float zero = 0.0f;
  glClearNamedFramebufferfv(m.fbo, GL_COLOR, 0, sky);
  glClearNamedFramebufferuiv(m.fbo, GL_COLOR, 1, zero4);
  glClearNamedFramebufferfv(m.fbo, GL_DEPTH, 0, &zero);
  glBindFramebuffer(GL_FRAMEBUFFER, m.fbo);
  r.draw_program(program, cam, fs);
  // The count: one invocation per pixel, atomics into three uints.
  glClearNamedBufferData(m.counts, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, nullptr);
  glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_FRAMEBUFFER_BARRIER_BIT);
  glUseProgram(m.count_prog);
  glBindImageTexture(0, m.lv, 0, GL_FALSE, 0, GL_READ_ONLY, GL_RG32UI);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, m.counts);
  glDispatchCompute(static_cast<GLuint>((m.w + 15) / 16), static_cast<GLuint>((m.h + 15) / 16), 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  std::uint32_t c[3] = {0, 0, 0};
  glGetNamedBufferSubData(m.counts, 0, sizeof c, c);
  return PopinCount{c[0], c[1], c[2]};
}

std::vector<std::uint8_t> StreamPass::read_colour(int& w, int& h) {
  Impl& m = *impl_;
  w = m.w;
  h = m.h;
  std::vector<std::uint8_t> px(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 4);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, m.fbo);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glBindBuffer(GL_PIXEL_PACK_BUFFER, 0);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, px.data());
  return px;
}

struct StreamedVt::Impl {
  GLuint prog = 0, phys = 0, pt_buf = 0;
  int slots_x = 0, side = 0, phys_side = 0;
  std::size_t page_bytes = 0;
  std::unique_ptr<StreamPass> pass;
};

StreamedVt::StreamedVt(Renderer& r, int tile, int border, int channels, std::int64_t slots, int levels)
    : impl_(std::make_unique<Impl>()), r_(r), channels_(channels), levels_(levels), slots_(slots) {
  if (tile < 1 || border < 0 || channels < 1 || channels > 4 || slots < 1 || slots > 0xffffff || levels < 1)
    throw InputError("gl", fmt::format("streamed VT: bad page geometry (tile {}, border {}, channels {}, slots {})", tile, border,
                                       channels, slots));
  if (levels_ > 32) throw InputError("gl", "streamed VT: more than 32 levels");
  Impl& m = *impl_;
  m.side = tile + 2 * border;
  m.slots_x = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(slots))));
  GLint max_side = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_side);
  if (static_cast<std::int64_t>(m.slots_x) * m.side > max_side)
    throw InputError("vt.pool_pages", fmt::format("{} pages of {}² texels need a {}² physical texture; this GL allows {}²", slots,
                                                  m.side, static_cast<std::int64_t>(m.slots_x) * m.side, max_side));
  m.phys_side = m.slots_x * m.side;
  m.page_bytes = static_cast<std::size_t>(m.side) * static_cast<std::size_t>(m.side) * static_cast<std::size_t>(channels);
  glCreateTextures(GL_TEXTURE_2D, 1, &m.phys);
  glTextureStorage2D(m.phys, 1, internal_of(channels), m.phys_side, m.phys_side);
  glTextureParameteri(m.phys, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTextureParameteri(m.phys, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTextureParameteri(m.phys, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTextureParameteri(m.phys, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  m.pass = std::make_unique<StreamPass>(m.page_bytes);
  // The page table's layout: each level's pages row by row, levels finest first.
  const TextureExtent ext = r.texture();
  int total = 0;
  for (int l = 0; l < levels_; ++l) {
    const std::int64_t lw = std::max<std::int64_t>(ext.width >> l, 1), lh = std::max<std::int64_t>(ext.height >> l, 1);
    level_off_.push_back(total);
    tiles_x_.push_back(static_cast<int>((lw + tile - 1) / tile));
    tiles_y_.push_back(static_cast<int>((lh + tile - 1) / tile));
    const std::int64_t n = static_cast<std::int64_t>(tiles_x_.back()) * tiles_y_.back();
    if (total + n > (1 << 26)) throw InputError("gl", "streamed VT: more than 2^26 pages in the page table");
    total += static_cast<int>(n);
  }
  pt_.assign(static_cast<std::size_t>(total), kNone);
  glCreateBuffers(1, &m.pt_buf);
  glNamedBufferData(m.pt_buf, static_cast<GLsizeiptr>(pt_.size() * 4), pt_.data(), GL_DYNAMIC_DRAW);
  m.prog = Renderer::link_program(kStreamFragment);
  const GLuint p = m.prog;
  glProgramUniform1i(p, glGetUniformLocation(p, "u_levels"), levels_);
  glProgramUniform1i(p, glGetUniformLocation(p, "u_tile"), tile);
  glProgramUniform1i(p, glGetUniformLocation(p, "u_border"), border);
  glProgramUniform1i(p, glGetUniformLocation(p, "u_slots_x"), m.slots_x);
  glProgramUniform1iv(p, glGetUniformLocation(p, "u_level_off"), static_cast<GLsizei>(level_off_.size()), level_off_.data());
  glProgramUniform2f(p, glGetUniformLocation(p, "u_phys_size"), static_cast<float>(m.phys_side), static_cast<float>(m.phys_side));
}

StreamedVt::~StreamedVt() {
  Impl& m = *impl_;
  m.pass.reset();
  glDeleteTextures(1, &m.phys);
  glDeleteBuffers(1, &m.pt_buf);
  glDeleteProgram(m.prog);
}

double StreamedVt::upload_gpu_ms() const { return impl_->pass->upload_gpu_ms(); }
std::uint64_t StreamedVt::timed_frames() const { return impl_->pass->timed_frames(); }

void StreamedVt::upload(const TileUpload& u) {
  ++uploads_;
  if (u.key.layer() != 0 || u.data == nullptr) return;
  Impl& m = *impl_;
  if (u.slot < 0 || u.slot >= slots_) throw std::runtime_error(fmt::format("gl upload: slot {} outside the pool of {}", u.slot, slots_));
  if (static_cast<int>(u.data->side) != m.side || static_cast<int>(u.data->channels) != channels_ || u.data->bytes != m.page_bytes)
    throw std::runtime_error(fmt::format("gl upload: page {}x{}x{} where the physical texture holds {}x{}x{}", u.data->side,
                                         u.data->side, u.data->channels, m.side, m.side, channels_));
  m.pass->copy(u.data->texels.get(), m.page_bytes, [&] {
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTextureSubImage2D(m.phys, 0, static_cast<GLint>(u.slot % m.slots_x) * m.side, static_cast<GLint>(u.slot / m.slots_x) * m.side,
                        m.side, m.side, format_of(channels_), GL_UNSIGNED_BYTE, nullptr);
  });
  ++copies_;
}

void StreamedVt::apply(const FrameUpdates& u) {
  Impl& m = *impl_;
  m.pass->end_uploads();
  for (const PageTableUpdate& p : u.page_table) {
    const TileKey page(0, p.page.level(), p.page.x(), p.page.y());  // a page: every layer at one slot
    if (p.slot < 0) table_.erase(page);
    else table_[page] = p.slot;
    pt_dirty_ = true;
  }
  if (!pt_dirty_) return;
  // Rebuilt from the coarsest level down: a page's own entry when resident, else its parent's
  // (the finest resident ancestor; kNone when no ancestor is resident).
  for (int l = levels_ - 1; l >= 0; --l) {
    const auto li = static_cast<std::size_t>(l);
    for (int y = 0; y < tiles_y_[li]; ++y)
      for (int x = 0; x < tiles_x_[li]; ++x) {
        const auto it = table_.find(TileKey(0, static_cast<std::uint32_t>(l), x, y));
        std::uint32_t e = kNone;
        if (it != table_.end()) e = static_cast<std::uint32_t>(it->second) | static_cast<std::uint32_t>(l) << 24;
        else if (l + 1 < levels_)
          e = pt_[static_cast<std::size_t>(level_off_[li + 1] + std::min(y / 2, tiles_y_[li + 1] - 1) * tiles_x_[li + 1] +
                                           std::min(x / 2, tiles_x_[li + 1] - 1))];
        pt_[static_cast<std::size_t>(level_off_[li] + y * tiles_x_[li] + x)] = e;
      }
  }
  glNamedBufferSubData(m.pt_buf, 0, static_cast<GLsizeiptr>(pt_.size() * 4), pt_.data());
  pt_dirty_ = false;
}

std::uint32_t StreamedVt::entry(int level, std::int64_t x, std::int64_t y) const {
  const auto li = static_cast<std::size_t>(level);
  return pt_[static_cast<std::size_t>(level_off_[li] + static_cast<int>(y) * tiles_x_[li] + static_cast<int>(x))];
}

PopinCount StreamedVt::draw(const Camera& cam, const FeedbackSettings& fs, int clamp, double sample_bias) {
  Impl& m = *impl_;
  glProgramUniform1i(m.prog, glGetUniformLocation(m.prog, "u_clamp"), std::clamp(clamp, 0, levels_ - 1));
  glProgramUniform1f(m.prog, glGetUniformLocation(m.prog, "u_sample_bias"), static_cast<float>(sample_bias));
  glBindTextureUnit(1, m.phys);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, m.pt_buf);
  return m.pass->draw(r_, m.prog, cam, fs);
}

std::vector<std::uint8_t> StreamedVt::read_colour(int& w, int& h) { return impl_->pass->read_colour(w, h); }

}  // namespace vtsim::gl
