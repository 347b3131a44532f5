#include "sim/trace/feedback_trace.h"

#include "core/atomic_file.h"

#include <zstd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <istream>
#include <sstream>

#include <fmt/format.h>

#include "core/error.h"
#include "core/hash.h"

namespace vtsim {

namespace {

constexpr char kMagic[8] = {'V', 'T', 'S', 'I', 'M', 'F', 'B', '1'};
constexpr char kBlockMagic[4] = {'B', 'L', 'K', '1'};
constexpr char kEndMagic[4] = {'E', 'N', 'D', '1'};
constexpr std::size_t kBlockHeaderBytes = 32;
constexpr std::size_t kEndBytes = 24;
constexpr std::uint8_t kHasPose = 1, kFresh = 2, kMeasured = 4;

void put_u32(std::string& s, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) s.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
}
void put_u64(std::string& s, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) s.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
}
void put_f64(std::string& s, double d) { put_u64(s, std::bit_cast<std::uint64_t>(d)); }
void put_var(std::string& s, std::uint64_t v) {
  while (v >= 0x80) {
    s.push_back(static_cast<char>((v & 0x7f) | 0x80));
    v >>= 7;
  }
  s.push_back(static_cast<char>(v));
}
std::uint64_t zigzag(std::int64_t v) { return (static_cast<std::uint64_t>(v) << 1) ^ static_cast<std::uint64_t>(v >> 63); }
std::int64_t unzigzag(std::uint64_t v) { return static_cast<std::int64_t>(v >> 1) ^ -static_cast<std::int64_t>(v & 1); }

std::uint32_t get_u32(const char* p) {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<std::uint32_t>(static_cast<unsigned char>(p[i])) << (8 * i);
  return v;
}
std::uint64_t get_u64(const char* p) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(static_cast<unsigned char>(p[i])) << (8 * i);
  return v;
}

bool tile_less(const FeedbackTile& a, const FeedbackTile& b) {
  if (a.layer != b.layer) return a.layer < b.layer;
  if (a.level != b.level) return a.level < b.level;
  if (a.x != b.x) return a.x < b.x;
  return a.y < b.y;
}

std::uint64_t level_tiles(std::int64_t texels, int level, std::uint32_t tile) {
  const std::int64_t at = level >= 63 ? 1 : std::max<std::int64_t>(1, (texels + (std::int64_t{1} << level) - 1) >> level);
  return (static_cast<std::uint64_t>(at) + tile - 1) / tile;
}

std::string header_bytes(const FeedbackHeader& h) {
  std::string s(kMagic, sizeof kMagic);
  put_u32(s, kFeedbackVersion);
  put_u32(s, 0);  // flags, reserved
  put_u64(s, static_cast<std::uint64_t>(h.texture.width));
  put_u64(s, static_cast<std::uint64_t>(h.texture.height));
  put_u32(s, h.tile_size);
  put_u32(s, h.levels);
  put_u32(s, h.layers);
  put_u32(s, h.feedback_width);
  put_u32(s, h.feedback_height);
  put_u32(s, h.image_width);
  put_u32(s, h.image_height);
  put_u32(s, 0);  // reserved
  put_f64(s, h.frame_rate);
  put_u64(s, fnv1a64(s));
  return s;
}

}  // namespace

std::uint64_t FeedbackHeader::tiles_x(int level) const { return level_tiles(texture.width, level, tile_size); }
std::uint64_t FeedbackHeader::tiles_y(int level) const { return level_tiles(texture.height, level, tile_size); }

void feedback_tiles(const SpanBuffer& sb, std::uint32_t tile_size, std::vector<FeedbackTile>& out) {
  out.clear();
  thread_local std::vector<ViewSample> expanded;
  const std::int64_t T = tile_size;
  const auto add = [&](int l, std::int64_t u, std::int64_t v, std::uint32_t n) {
    const auto x = static_cast<std::uint64_t>((u >> l) / T), y = static_cast<std::uint64_t>((v >> l) / T);
    if (!out.empty() && out.back().level == static_cast<std::uint32_t>(l) && out.back().x == x && out.back().y == y) {
      out.back().samples += n;
      return;
    }
    out.push_back(FeedbackTile{static_cast<std::uint32_t>(l), 0, x, y, n});
  };
  for (const ViewSpan& sp : sb.spans) {
    const int l = sp.level;
    if ((sp.u_lo >> l) / T == (sp.u_hi >> l) / T && (sp.v_lo >> l) / T == (sp.v_hi >> l) / T) {
      add(l, sp.u_lo, sp.v_lo, sp.count);
      continue;
    }
    expanded.clear();
    expand_span(sb, sp, expanded);
    for (const ViewSample& s : expanded) add(desired_level(s.lod, sb.levels), s.u, s.v, 1);
  }
  std::sort(out.begin(), out.end(), tile_less);
  std::size_t w = 0;
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (w > 0 && out[w - 1].level == out[i].level && out[w - 1].x == out[i].x && out[w - 1].y == out[i].y)
      out[w - 1].samples += out[i].samples;
    else
      out[w++] = out[i];
  }
  out.resize(w);
}

// ---- writer ----

FeedbackWriter::FeedbackWriter(const std::string& path, const FeedbackHeader& h, std::uint32_t frames_per_block)
    : path_(path), h_(h), per_block_(std::clamp<std::uint32_t>(frames_per_block, 1, kFeedbackMaxFramesPerBlock)) {
  out_ = std::make_unique<AtomicFile>(path);
  const std::string hb = header_bytes(h);
  out_->write(hb);
  bytes_ = hb.size();
}

FeedbackWriter::~FeedbackWriter() = default;

void FeedbackWriter::add(const FeedbackFrame& f) {
  if (finished_) throw std::logic_error("FeedbackWriter::add after finish");
  if (frames_ > 0 && !(f.t_s > last_t_)) throw std::logic_error("FeedbackWriter::add: frame times must increase");
  last_t_ = f.t_s;
  if (block_frames_ == 0) block_first_ = frames_;
  const std::uint8_t flags = static_cast<std::uint8_t>((f.has_pose ? kHasPose : 0) | (f.fresh ? kFresh : 0) | (f.measured ? kMeasured : 0));
  raw_.push_back(static_cast<char>(flags));
  put_f64(raw_, f.t_s);
  if (f.has_pose) {
    put_f64(raw_, f.pose.pos_m.x);
    put_f64(raw_, f.pose.pos_m.y);
    put_f64(raw_, f.pose.pos_m.z);
    put_f64(raw_, f.pose.q.w);
    put_f64(raw_, f.pose.q.x);
    put_f64(raw_, f.pose.q.y);
    put_f64(raw_, f.pose.q.z);
    put_f64(raw_, f.pose.vfov_deg);
  }
  if (f.fresh) {
    put_var(raw_, f.tiles.size());
    FeedbackTile prev{};
    for (const FeedbackTile& t : f.tiles) {
      // (layer, level) as deltas (mostly 0), x and y as signed deltas from the previous tile.
      put_var(raw_, t.layer - prev.layer);
      put_var(raw_, t.layer == prev.layer ? t.level - prev.level : t.level);
      put_var(raw_, zigzag(static_cast<std::int64_t>(t.x - prev.x)));
      put_var(raw_, zigzag(static_cast<std::int64_t>(t.y - prev.y)));
      put_var(raw_, t.samples);
      prev = t;
    }
  }
  ++frames_;
  if (++block_frames_ == per_block_) flush_block();
}

void FeedbackWriter::flush_block() {
  if (block_frames_ == 0) return;
  std::string comp(ZSTD_compressBound(raw_.size()), '\0');
  const std::size_t n = ZSTD_compress(comp.data(), comp.size(), raw_.data(), raw_.size(), 9);
  if (ZSTD_isError(n)) throw std::runtime_error(std::string("zstd compress: ") + ZSTD_getErrorName(n));
  comp.resize(n);
  std::string bh(kBlockMagic, sizeof kBlockMagic);
  put_u32(bh, block_frames_);
  put_u64(bh, block_first_);
  put_u32(bh, static_cast<std::uint32_t>(raw_.size()));
  put_u32(bh, static_cast<std::uint32_t>(comp.size()));
  put_u64(bh, fnv1a64(raw_));
  out_->write(bh);
  out_->write(comp);
  bytes_ += bh.size() + comp.size();
  raw_.clear();
  block_frames_ = 0;
}

void FeedbackWriter::finish() {
  if (finished_) return;
  flush_block();
  std::string e(kEndMagic, sizeof kEndMagic);
  put_u32(e, 0);
  put_u64(e, frames_);
  put_u64(e, fnv1a64(e));
  out_->write(e);
  bytes_ += e.size();
  out_->commit();
  finished_ = true;
}

// ---- reader ----

FeedbackReader::FeedbackReader(const std::string& path) : name_(path) {
  auto f = std::make_unique<std::ifstream>(path, std::ios::binary);
  if (!*f) throw InputError(path, "cannot open the feedback trace");
  in_ = std::move(f);
  read_header();
}

FeedbackReader::FeedbackReader(std::unique_ptr<std::istream> in, std::string name) : in_(std::move(in)), name_(std::move(name)) {
  read_header();
}

FeedbackReader::~FeedbackReader() = default;

void FeedbackReader::fail(const std::string& field, const std::string& what) const {
  throw InputError(fmt::format("{}:frame {}", name_, frame_), fmt::format("field '{}': {}", field, what));
}

void FeedbackReader::read_header() {
  char b[kFeedbackHeaderBytes];
  in_->read(b, sizeof b);
  const auto bad = [&](const std::string& field, const std::string& what) {
    throw InputError(name_ + ":header", fmt::format("field '{}': {}", field, what));
  };
  if (in_->gcount() != static_cast<std::streamsize>(sizeof b)) bad("magic", "truncated: the 80-byte header is incomplete");
  if (std::memcmp(b, kMagic, sizeof kMagic) != 0) bad("magic", "not a vtsim feedback trace (docs/feedback.md)");
  if (const std::uint32_t v = get_u32(b + 8); v != kFeedbackVersion) bad("version", fmt::format("{} is not supported (this vtsim reads {})", v, kFeedbackVersion));
  if (get_u64(b + 72) != fnv1a64(std::string_view(b, 72))) bad("checksum", "the header is corrupt (checksum mismatch)");
  if (get_u32(b + 12) != 0 || get_u32(b + 60) != 0) bad("flags", "reserved fields are not 0 (a later version's file?)");
  const std::uint64_t w = get_u64(b + 16), h = get_u64(b + 24);
  if (w < 1 || h < 1 || w > (std::uint64_t{1} << 40) || h > (std::uint64_t{1} << 40))
    bad("texture", fmt::format("{}x{} texels is outside [1, 2^40]", w, h));
  h_.texture = TextureExtent{static_cast<std::int64_t>(w), static_cast<std::int64_t>(h)};
  h_.tile_size = get_u32(b + 32);
  if (h_.tile_size < 1 || h_.tile_size > (1u << 24)) bad("tile_size", fmt::format("{} is outside [1, 2^24]", h_.tile_size));
  h_.levels = get_u32(b + 36);
  const auto mips = static_cast<std::uint32_t>(mip_level_count(h_.texture));
  if (h_.levels < 1 || h_.levels > mips) bad("levels", fmt::format("{} is outside [1, {}] (the texture's mip levels)", h_.levels, mips));
  h_.layers = get_u32(b + 40);
  if (h_.layers < 1 || h_.layers > 16) bad("layers", fmt::format("{} is outside [1, 16]", h_.layers));
  h_.feedback_width = get_u32(b + 44);
  h_.feedback_height = get_u32(b + 48);
  h_.image_width = get_u32(b + 52);
  h_.image_height = get_u32(b + 56);
  h_.frame_rate = std::bit_cast<double>(get_u64(b + 64));
  if (!std::isfinite(h_.frame_rate) || h_.frame_rate <= 0.0 || h_.frame_rate > 10000.0)
    bad("frame_rate", fmt::format("{} is outside (0, 10000] frames a second", h_.frame_rate));
}

bool FeedbackReader::load_block() {
  char b[kBlockHeaderBytes];
  in_->read(b, 4);
  if (in_->gcount() != 4) fail("block", fmt::format("truncated at byte {}: no end record (the file was cut)", offset_));
  if (std::memcmp(b, kEndMagic, 4) == 0) {
    in_->read(b + 4, kEndBytes - 4);
    if (in_->gcount() != static_cast<std::streamsize>(kEndBytes - 4)) fail("end", "truncated end record");
    if (get_u64(b + 16) != fnv1a64(std::string_view(b, 16))) fail("end", "the end record is corrupt (checksum mismatch)");
    if (get_u64(b + 8) != frame_) fail("end", fmt::format("the end record counts {} frames, the blocks hold {}", get_u64(b + 8), frame_));
    done_ = true;
    return false;
  }
  if (std::memcmp(b, kBlockMagic, 4) != 0) fail("block", fmt::format("no block or end record at byte {} (corrupt)", offset_));
  in_->read(b + 4, kBlockHeaderBytes - 4);
  if (in_->gcount() != static_cast<std::streamsize>(kBlockHeaderBytes - 4)) fail("block", "truncated block header");
  const std::uint32_t frames = get_u32(b + 4);
  const std::uint64_t first = get_u64(b + 8);
  const std::uint32_t raw_n = get_u32(b + 16), comp_n = get_u32(b + 20);
  const std::uint64_t sum = get_u64(b + 24);
  if (frames < 1 || frames > kFeedbackMaxFramesPerBlock) fail("block.frames", fmt::format("{} is outside [1, {}]", frames, kFeedbackMaxFramesPerBlock));
  if (first != frame_) fail("block.first_frame", fmt::format("{}: frames out of order (expected {})", first, frame_));
  if (raw_n > kFeedbackMaxBlockBytes || comp_n > kFeedbackMaxBlockBytes || comp_n == 0)
    fail("block.bytes", fmt::format("{} / {} bytes is outside the bound {}", raw_n, comp_n, kFeedbackMaxBlockBytes));
  // Read in pieces, so a header claiming more than the file holds costs only what is there; and
  // the frame's recorded content size checked before the block is inflated into raw_n bytes.
  std::string comp;
  while (comp.size() < comp_n) {
    const std::size_t at = comp.size(), piece = std::min<std::size_t>(comp_n - at, std::size_t{1} << 20);
    comp.resize(at + piece);
    in_->read(comp.data() + at, static_cast<std::streamsize>(piece));
    if (in_->gcount() != static_cast<std::streamsize>(piece)) fail("block", fmt::format("truncated: the block at byte {} is cut", offset_));
  }
  if (ZSTD_getFrameContentSize(comp.data(), comp.size()) != raw_n)
    fail("block", fmt::format("the block at byte {} is corrupt (its zstd frame does not hold {} bytes)", offset_, raw_n));
  raw_.assign(raw_n, '\0');
  const std::size_t n = ZSTD_decompress(raw_.data(), raw_.size(), comp.data(), comp.size());
  if (ZSTD_isError(n) || n != raw_n) fail("block", fmt::format("the block at byte {} is corrupt (zstd: {})", offset_, ZSTD_isError(n) ? ZSTD_getErrorName(n) : "size mismatch"));
  if (fnv1a64(raw_) != sum) fail("block.checksum", fmt::format("the block at byte {} is corrupt (checksum mismatch)", offset_));
  offset_ += kBlockHeaderBytes + comp_n;
  pos_ = 0;
  left_ = frames;
  return true;
}

bool FeedbackReader::next(FeedbackFrame& f) {
  if (done_) return false;
  if (left_ == 0) {
    if (!load_block()) return false;
  }
  const auto need = [&](std::size_t n, const char* field) {
    if (raw_.size() - pos_ < n) fail(field, "truncated inside its block");
  };
  const auto var = [&](const char* field) -> std::uint64_t {
    std::uint64_t v = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      need(1, field);
      const auto c = static_cast<unsigned char>(raw_[pos_++]);
      v |= static_cast<std::uint64_t>(c & 0x7f) << shift;
      if (!(c & 0x80)) return v;
    }
    fail(field, "malformed varint");
  };
  const auto f64 = [&](const char* field) {
    need(8, field);
    const double d = std::bit_cast<double>(get_u64(raw_.data() + pos_));
    pos_ += 8;
    if (!std::isfinite(d)) fail(field, "not a finite number");
    return d;
  };
  need(1, "flags");
  const auto flags = static_cast<std::uint8_t>(raw_[pos_++]);
  if (flags & ~(kHasPose | kFresh | kMeasured)) fail("flags", fmt::format("unknown bits 0x{:02x}", flags));
  f.has_pose = flags & kHasPose;
  f.fresh = flags & kFresh;
  f.measured = flags & kMeasured;
  f.t_s = f64("time");
  if (frame_ > 0 && !(f.t_s > last_t_)) fail("time", fmt::format("{} s is not after the previous frame's {} s: frames out of order", f.t_s, last_t_));
  if (frame_ == 0 && !f.fresh) fail("flags", "the first frame must carry feedback (fresh)");
  if (f.has_pose) {
    f.pose.t_s = f.t_s;
    f.pose.pos_m.x = f64("pose.x");
    f.pose.pos_m.y = f64("pose.y");
    f.pose.pos_m.z = f64("pose.z");
    f.pose.q.w = f64("pose.qw");
    f.pose.q.x = f64("pose.qx");
    f.pose.q.y = f64("pose.qy");
    f.pose.q.z = f64("pose.qz");
    f.pose.vfov_deg = f64("pose.vfov");
    const double n2 = f.pose.q.w * f.pose.q.w + f.pose.q.x * f.pose.q.x + f.pose.q.y * f.pose.q.y + f.pose.q.z * f.pose.q.z;
    if (std::fabs(n2 - 1.0) > 1e-3) fail("pose.q", "not a unit quaternion");
    if (f.pose.vfov_deg <= 0.0 || f.pose.vfov_deg >= 180.0) fail("pose.vfov", fmt::format("{} degrees is outside (0, 180)", f.pose.vfov_deg));
  } else {
    f.pose = Pose{};
    f.pose.t_s = f.t_s;
  }
  f.tiles.clear();
  if (f.fresh) {
    const std::uint64_t n = var("tiles");
    // Each tile takes at least 5 bytes: a count beyond the block's bytes is corrupt, not an allocation.
    if (n > (raw_.size() - pos_) / 5) fail("tiles", fmt::format("{} tiles do not fit the block's remaining {} bytes", n, raw_.size() - pos_));
    f.tiles.reserve(n);
    FeedbackTile prev{};
    for (std::uint64_t i = 0; i < n; ++i) {
      FeedbackTile t;
      const std::uint64_t dlayer = var("tile.layer");
      if (dlayer >= h_.layers) fail("tile.layer", fmt::format("tile {}: layer delta {} leaves the {} layers", i, dlayer, h_.layers));
      t.layer = prev.layer + static_cast<std::uint32_t>(dlayer);
      const std::uint64_t lv = var("tile.level");
      if (t.layer >= h_.layers) fail("tile.layer", fmt::format("tile {}: layer {} is not below the {} layers", i, t.layer, h_.layers));
      const std::uint64_t level = t.layer == prev.layer ? prev.level + lv : lv;
      if (level >= h_.levels) fail("tile.level", fmt::format("tile {}: level {} is not below the {} levels", i, level, h_.levels));
      t.level = static_cast<std::uint32_t>(level);
      t.x = prev.x + static_cast<std::uint64_t>(unzigzag(var("tile.x")));
      t.y = prev.y + static_cast<std::uint64_t>(unzigzag(var("tile.y")));
      const std::uint64_t s = var("tile.samples");
      const int l = static_cast<int>(t.level);
      if (t.x >= h_.tiles_x(l) || t.y >= h_.tiles_y(l))
        fail("tile.x", fmt::format("tile {}: ({}, {}) at level {} is outside the texture ({} x {} tiles)", i, t.x, t.y, l, h_.tiles_x(l), h_.tiles_y(l)));
      if (s < 1 || s > 0xffffffffu) fail("tile.samples", fmt::format("tile {}: {} is outside [1, 2^32)", i, s));
      t.samples = static_cast<std::uint32_t>(s);
      if (i > 0 && !tile_less(prev, t)) fail("tile", fmt::format("tile {}: not after the previous tile (tiles sorted by layer, level, x, y; distinct)", i));
      f.tiles.push_back(t);
      prev = t;
    }
  }
  last_t_ = f.t_s;
  ++frame_;
  if (--left_ == 0 && pos_ != raw_.size()) fail("block", "bytes left after the block's last frame (corrupt)");
  return true;
}

bool is_feedback_trace(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char b[sizeof kMagic] = {};
  in.read(b, sizeof b);
  return in.gcount() == static_cast<std::streamsize>(sizeof b) && std::memcmp(b, kMagic, sizeof kMagic) == 0;
}

Trace feedback_trace_poses(const std::string& path) {
  FeedbackReader r(path);
  Trace t;
  const std::string file = path.substr(path.find_last_of('/') + 1);
  t.name = file.substr(0, file.find_last_of('.'));
  t.source_path = path;
  t.image_width = static_cast<int>(r.header().image_width);
  t.image_height = static_cast<int>(r.header().image_height);
  FeedbackFrame f;
  while (r.next(f)) t.poses.push_back(f.pose);
  return t;
}

FeedbackTrace read_feedback_trace(const std::string& path) {
  FeedbackReader r(path);
  FeedbackTrace t;
  t.header = r.header();
  FeedbackFrame f;
  while (r.next(f)) t.frames.push_back(f);
  return t;
}

}  // namespace vtsim
