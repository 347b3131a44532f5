#include "stream/store/store_builder.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <exception>
#include <filesystem>
#include <numeric>
#include <thread>

#include <fmt/format.h>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/host_memory.h"
#include "core/image_io.h"
#include "core/utf8.h"

namespace vtsim {

using namespace store;
namespace fs = std::filesystem;

namespace {

std::string errno_text() { return std::strerror(errno); }

void write_all(int fd, const std::uint8_t* p, std::size_t n, std::uint64_t offset, const std::string& path) {
  while (n > 0) {
    const ssize_t r = ::pwrite(fd, p, n, static_cast<off_t>(offset));
    if (r < 0) {
      if (errno == EINTR) continue;
      throw InputError(path, "write failed: " + errno_text());
    }
    p += r;
    n -= static_cast<std::size_t>(r);
    offset += static_cast<std::uint64_t>(r);
  }
}

constexpr std::uint64_t kMaxWriterTiles = std::uint64_t{1} << 27;

void validate_spec(const StoreSpec& s) {
  if (s.tile < 1 || s.tile > kMaxTileSize) throw InputError("--tile", dec(s.tile) + " is out of range 1.." + dec(kMaxTileSize));
  if (s.border > kMaxBorder || s.tile + 2 * s.border > kMaxStoredSide)
    throw InputError("--border", dec(s.border) + " is out of range (border <= " + dec(kMaxBorder) + ", tile + 2*border <= " +
                                     dec(kMaxStoredSide) + ")");
  const std::uint64_t max_extent = static_cast<std::uint64_t>(TileKey::kMaxCoord + 1) * s.tile;
  if (s.width < 1 || s.height < 1 || s.width > max_extent || s.height > max_extent)
    throw InputError("--size", dec(s.width) + "x" + dec(s.height) + " is out of range (1.." + dec(max_extent) + " a side at tile " +
                                   dec(s.tile) + ")");
  const std::uint32_t full = full_level_count(s.width, s.height);
  if (s.levels > full)
    throw InputError("--levels", dec(s.levels) + " is more than the " + dec(full) + " levels down to 1x1 of " + dec(s.width) + "x" + dec(s.height));
  if (s.layers.empty() || s.layers.size() > kMaxLayers)
    throw InputError("--layers", dec(s.layers.size()) + " layers; a store has 1.." + dec(kMaxLayers));
  // The writer holds the whole index in memory (32 B a tile): 2^27 tiles = 4 GiB. The default
  // 2^20² texture at tile 128 has 89 M tiles (~2.9 GB of index, 6.6 TB of data).
  const std::uint64_t tiles = Geometry::make(s.width, s.height, s.tile, s.border, s.levels ? s.levels : full,
                                             static_cast<std::uint32_t>(s.layers.size()))
                                  .tile_count();
  if (tiles > kMaxWriterTiles)
    throw InputError("--size", dec(s.width) + "x" + dec(s.height) + " at tile " + dec(s.tile) + " is " + dec(tiles) +
                                   " tiles; a store has at most " + dec(kMaxWriterTiles) + " (use larger tiles or a smaller texture)");
  for (std::size_t i = 0; i < s.layers.size(); ++i) {
    const StoreLayerSpec& L = s.layers[i];
    const std::string where = "layer " + dec(i) + " ('" + L.name + "')";
    if (const std::string why = layer_name_problem(L.name); !why.empty()) throw InputError("--layer-names", where + ": " + why);
    if (L.channels < 1 || L.channels > kMaxChannels)
      throw InputError(where, dec(L.channels) + " channels; a layer has 1.." + dec(kMaxChannels));
    if (!decoder_for(L.codec.id).supports_channels(static_cast<int>(L.channels)))
      throw InputError("--codec", where + ": " + std::string(codec_name(L.codec.id)) + " cannot store " + dec(L.channels) + " channels");
    for (std::size_t j = 0; j < i; ++j)
      if (s.layers[j].name == L.name) throw InputError("--layer-names", "layer name '" + L.name + "' is used twice");
  }
}

}  // namespace

// ---- StoreWriter -------------------------------------------------------------------------------

StoreWriter::StoreWriter(const std::string& out_path, const StoreSpec& spec) : out_path_(out_path) {
  validate_spec(spec);
  // The store is renamed into place at the end: that would replace a device (/dev/null, run as
  // root), a FIFO or a socket with a regular file.
  std::error_code ec;
  const fs::file_status st = fs::status(out_path, ec);
  if (fs::exists(st) && !fs::is_regular_file(st))
    throw InputError(out_path, "exists and is not a regular file: a store is written only to a new or regular file");
  const std::uint32_t levels = spec.levels ? spec.levels : full_level_count(spec.width, spec.height);
  header_.geom = Geometry::make(spec.width, spec.height, spec.tile, spec.border, levels,
                                static_cast<std::uint32_t>(spec.layers.size()));
  for (const StoreLayerSpec& L : spec.layers) {
    LayerInfo info;
    info.name = L.name;
    info.channels = L.channels;
    info.codec = L.codec.id;
    info.codec_param = L.codec.param;
    info.transfer = L.transfer;
    header_.layers.push_back(info);
    codecs_.push_back(make_codec(L.codec.id, L.codec.param, "--codec"));
  }
  const std::uint64_t n = header_.geom.tile_count();
  header_.index_offset = kHeaderBlockBytes;
  header_.index_bytes = n * kIndexEntryBytes;
  header_.data_offset = round_up(header_.index_offset + header_.index_bytes, kAlign);
  index_.resize(static_cast<std::size_t>(n));
  written_.assign(static_cast<std::size_t>(n), 0);
  end_ = buf_start_ = header_.data_offset;

  // Written whole or not at all: a temporary beside the store, renamed over it by commit().
  file_ = std::make_unique<AtomicFile>(out_path);
  fd_ = file_->fd();
  tmp_path_ = file_->temp_path();
}

StoreWriter::~StoreWriter() = default;  // file_ removes the temporary unless committed

EncodedTile StoreWriter::encode(TileKey k, const std::uint8_t* texels) const {
  EncodedTile t;
  t.key = k;
  const int side = static_cast<int>(header_.geom.stored_side());
  const std::uint32_t layer = k.layer();
  const std::uint32_t want = tile_bytes(layer);
  try {
    t.payload = codecs_[layer]->encode(texels, side, side, static_cast<int>(header_.layers[layer].channels));
  } catch (const CodecError& e) {
    throw InputError(out_path_ + ": " + describe(k), std::string("encode failed: ") + e.what());
  }
  t.codec = header_.layers[layer].codec;
  if (t.payload.size() >= want) {  // incompressible: raw is smaller or equal, and cheapest to decode
    t.payload.assign(texels, texels + want);
    t.codec = CodecId::raw;
  }
  return t;
}

void StoreWriter::append(const EncodedTile& t) {
  const Geometry& g = header_.geom;
  if (!g.contains(t.key)) throw InputError(out_path_ + ": " + describe(t.key), "is outside the store");
  const std::uint64_t slot = g.slot(t.key);
  if (written_[slot]) throw InputError(out_path_ + ": " + describe(t.key), "written twice");
  const std::uint32_t want = tile_bytes(t.key.layer());
  if (t.payload.empty() || t.payload.size() > want || (t.codec == CodecId::raw && t.payload.size() != want))
    throw InputError(out_path_ + ": " + describe(t.key), "payload of " + dec(t.payload.size()) + " bytes is out of range");
  IndexEntry& e = index_[slot];
  e.offset = end_;
  e.stored_bytes = static_cast<std::uint32_t>(t.payload.size());
  e.decoded_bytes = want;
  e.checksum = checksum64(t.payload.data(), t.payload.size());
  e.codec = t.codec;
  buffer_.insert(buffer_.end(), t.payload.begin(), t.payload.end());
  buffer_.resize(static_cast<std::size_t>(round_up(buffer_.size(), kAlign)), 0);  // zero padding
  end_ = buf_start_ + buffer_.size();
  written_[slot] = 1;
  ++tiles_written_;
  stored_bytes_ += e.stored_bytes;
  decoded_bytes_ += e.decoded_bytes;
  if (buffer_.size() >= (std::size_t{8} << 20)) flush_buffer();
}

void StoreWriter::flush_buffer() {
  write_all(fd_, buffer_.data(), buffer_.size(), buf_start_, tmp_path_);
  buf_start_ += buffer_.size();
  buffer_.clear();
}

void StoreWriter::commit() {
  if (committed_) return;
  const std::uint64_t n = header_.geom.tile_count();
  if (tiles_written_ != n) {
    for (std::uint64_t s = 0; s < n; ++s)
      if (!written_[s])
        throw InputError(out_path_, dec(n - tiles_written_) + " tiles were never written, first " + describe(header_.geom.key_of_slot(s)));
  }
  flush_buffer();
  std::vector<std::uint8_t> idx(static_cast<std::size_t>(header_.index_bytes));
  for (std::uint64_t s = 0; s < n; ++s) encode_index_entry(index_[s], idx.data() + s * kIndexEntryBytes);
  header_.index_checksum = checksum64(idx.data(), idx.size());
  header_.file_bytes = end_;
  // Zero the gap between the index end and data_offset so the file has no unwritten holes.
  idx.resize(static_cast<std::size_t>(header_.data_offset - header_.index_offset), 0);
  write_all(fd_, idx.data(), idx.size(), header_.index_offset, tmp_path_);
  const std::vector<std::uint8_t> head = encode_header(header_);
  write_all(fd_, head.data(), head.size(), 0, tmp_path_);
  if (tmp_path_ != out_path_ && ::ftruncate(fd_, static_cast<off_t>(end_)) != 0)
    throw InputError(tmp_path_, "ftruncate failed: " + errno_text());
  fd_ = -1;
  file_->commit();  // fsync, rename over the store, fsync the directory
  committed_ = true;
}

// ---- parallel, ordered encoding ----------------------------------------------------------------

void encode_in_order(StoreWriter& writer, std::uint64_t count, unsigned threads,
                     const std::function<void(std::uint64_t, std::vector<EncodedTile>&)>& produce,
                     const ProgressFn& progress) {
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  // A window of items is produced in parallel, then appended in order: bounded memory (window
  // tiles) and a file that does not depend on scheduling.
  const std::uint64_t window = std::uint64_t{threads} * 16;
  std::vector<std::vector<EncodedTile>> results;
  for (std::uint64_t begin = 0; begin < count; begin += window) {
    const std::uint64_t end = std::min(count, begin + window);
    results.assign(static_cast<std::size_t>(end - begin), {});
    std::atomic<std::uint64_t> next{begin};
    std::exception_ptr failure;
    std::atomic<bool> failed{false};
    auto work = [&] {
      for (std::uint64_t i; !failed.load(std::memory_order_relaxed) && (i = next.fetch_add(1)) < end;) {
        try {
          produce(i, results[static_cast<std::size_t>(i - begin)]);
        } catch (...) {
          if (!failed.exchange(true)) failure = std::current_exception();
        }
      }
    };
    if (threads == 1 || end - begin == 1) {
      work();
    } else {
      std::vector<std::thread> pool;
      const unsigned n = static_cast<unsigned>(std::min<std::uint64_t>(threads, end - begin));
      for (unsigned t = 0; t < n; ++t) pool.emplace_back(work);
      for (auto& t : pool) t.join();
    }
    if (failure) std::rethrow_exception(failure);
    for (auto& r : results)
      for (auto& t : r) writer.append(t);
    if (progress) progress(static_cast<double>(end) / static_cast<double>(count));
  }
}

// ---- images and mips ---------------------------------------------------------------------------

namespace {

// sRGB transfer (IEC 61966-2-1).
float srgb_to_linear(float s) { return s <= 0.04045f ? s / 12.92f : std::pow((s + 0.055f) / 1.055f, 2.4f); }
float linear_to_srgb(float l) { return l <= 0.0031308f ? l * 12.92f : 1.055f * std::pow(l, 1.0f / 2.4f) - 0.055f; }

const float* srgb_lut() {
  static const auto lut = [] {
    std::vector<float> t(256);
    for (int i = 0; i < 256; ++i) t[static_cast<std::size_t>(i)] = srgb_to_linear(static_cast<float>(i) / 255.0f);
    return t;
  }();
  return lut.data();
}

// Colour channels carry the transfer curve; alpha (channel 1 of 2, channel 3 of 4) is linear.
bool is_colour(std::uint32_t ch, std::uint32_t channels) { return channels <= 2 ? ch == 0 : ch < 3; }

std::uint8_t quantise(float v) {
  const float c = std::clamp(v, 0.0f, 1.0f) * 255.0f + 0.5f;
  return static_cast<std::uint8_t>(c);
}

struct FloatImage {
  std::uint64_t width = 0, height = 0;
  std::uint32_t channels = 0;
  std::vector<float> v;  // linear values in [0, 1]
};

// Level-0 texels covered by texel i of level l: [i*2^l, min((i+1)*2^l, extent0)).
std::uint64_t footprint(std::uint64_t i, std::uint32_t l, std::uint64_t extent0) {
  const std::uint64_t b = i << l, e = std::min((i + 1) << l, extent0);
  return e - b;
}

// Level l+1 from level l (given by `get(x, y, ch)` in linear light), area-weighted (see header).
template <class Get>
FloatImage downsample(std::uint64_t w, std::uint64_t h, std::uint32_t c, std::uint32_t l, std::uint64_t w0,
                      std::uint64_t h0, Get get) {
  FloatImage out;
  out.width = (w + 1) / 2;
  out.height = (h + 1) / 2;
  out.channels = c;
  out.v.resize(static_cast<std::size_t>(out.width * out.height * c));
  for (std::uint64_t y = 0; y < out.height; ++y) {
    const std::uint64_t y0 = 2 * y, y1 = std::min(2 * y + 1, h - 1);
    const double wy0 = static_cast<double>(footprint(y0, l, h0));
    const double wy1 = y1 != y0 ? static_cast<double>(footprint(y1, l, h0)) : 0.0;
    for (std::uint64_t x = 0; x < out.width; ++x) {
      const std::uint64_t x0 = 2 * x, x1 = std::min(2 * x + 1, w - 1);
      const double wx0 = static_cast<double>(footprint(x0, l, w0));
      const double wx1 = x1 != x0 ? static_cast<double>(footprint(x1, l, w0)) : 0.0;
      const double norm = 1.0 / ((wx0 + wx1) * (wy0 + wy1));
      float* o = &out.v[static_cast<std::size_t>((y * out.width + x) * c)];
      for (std::uint32_t ch = 0; ch < c; ++ch) {
        double s = wx0 * wy0 * get(x0, y0, ch);
        if (wx1 > 0) s += wx1 * wy0 * get(x1, y0, ch);
        if (wy1 > 0) s += wx0 * wy1 * get(x0, y1, ch);
        if (wx1 > 0 && wy1 > 0) s += wx1 * wy1 * get(x1, y1, ch);
        o[ch] = static_cast<float>(s * norm);
      }
    }
  }
  return out;
}

Image8 quantise_image(const FloatImage& f, Transfer transfer) {
  Image8 q;
  q.width = f.width;
  q.height = f.height;
  q.channels = f.channels;
  q.texels = std::vector<std::uint8_t>(f.v.size());
  for (std::size_t i = 0; i < f.v.size(); ++i) {
    const auto ch = static_cast<std::uint32_t>(i % f.channels);
    const float v = f.v[i];
    q.texels[i] = quantise(transfer == Transfer::srgb && is_colour(ch, f.channels) ? linear_to_srgb(v) : v);
  }
  return q;
}

// Walks the mip chain one level at a time, keeping only the current level (8-bit, what is
// stored) and its float form (what the next level is filtered from).
class MipWalker {
 public:
  MipWalker(Image8 level0, Transfer transfer)
      : q_(std::move(level0)), transfer_(transfer), w0_(q_.width), h0_(q_.height) {}
  const Image8& current() const { return q_; }
  void advance() {
    const std::uint32_t c = q_.channels;
    FloatImage next;
    if (level_ == 0) {
      const float* lut = srgb_lut();
      const bool srgb = transfer_ == Transfer::srgb;
      next = downsample(q_.width, q_.height, c, 0, w0_, h0_, [&](std::uint64_t x, std::uint64_t y, std::uint32_t ch) {
        const std::uint8_t v = q_.at(x, y)[ch];
        return static_cast<double>(srgb && is_colour(ch, c) ? lut[v] : static_cast<float>(v) / 255.0f);
      });
    } else {
      const FloatImage& f = f_;
      next = downsample(f.width, f.height, c, level_, w0_, h0_, [&](std::uint64_t x, std::uint64_t y, std::uint32_t ch) {
        return static_cast<double>(f.v[static_cast<std::size_t>((y * f.width + x) * c + ch)]);
      });
    }
    f_ = std::move(next);
    q_ = quantise_image(f_, transfer_);
    ++level_;
  }

 private:
  Image8 q_;
  FloatImage f_;
  Transfer transfer_;
  std::uint64_t w0_, h0_;
  std::uint32_t level_ = 0;
};

// The most the mip walk holds at once, in bytes, and the layer being reduced then. The peak is
// the step to level 1 (later levels are 4× smaller): MipWalker::advance builds level 1 in float
// beside level 0 and quantises it before level 0 is dropped, one layer after another, so the
// layers already reduced hold level 1 in float and 8 bits (5 bytes a value), the layer being
// reduced its level 0 and the same, and the layers after it their level 0.
std::pair<double, std::size_t> mip_walk_peak(const std::vector<image_io::ImageSpec>& layers) {
  std::vector<double> level0, level1;
  for (const image_io::ImageSpec& s : layers) {
    const double c = std::min(s.channels, 4);
    level0.push_back(static_cast<double>(s.width) * static_cast<double>(s.height) * c);
    level1.push_back(std::ceil(s.width / 2.0) * std::ceil(s.height / 2.0) * c * 5.0);
  }
  std::pair<double, std::size_t> peak{0.0, 0};
  double reduced = 0.0, unreduced = std::accumulate(level0.begin(), level0.end(), 0.0);
  for (std::size_t i = 0; i < layers.size(); ++i) {
    unreduced -= level0[i];
    const double bytes = reduced + level0[i] + level1[i] + unreduced;
    if (bytes > peak.first) peak = {bytes, i};
    reduced += level1[i];
  }
  return peak;
}

}  // namespace

// Rows read_image8 reads at a time: 16 MiB amortises OpenImageIO's per-call work and is small
// beside any image large enough for the memory check to matter.
constexpr std::size_t kReadChunkBytes = std::size_t{16} << 20;

Image8 read_image8(const std::string& path, Transfer transfer, std::uint64_t max_bytes, bool accept_damaged) {
  auto in = image_io::ImageReader::open_file(path, /*unassociated_alpha=*/true);  // texels as stored
  if (!in) {
    const std::string& e = in.error();
    throw InputError(path, "cannot read the image" + (e.empty() ? "" : ": " + e));
  }
  const image_io::ImageSpec& s = in.spec();
  if (s.width < 1 || s.height < 1 || s.depth != 1 || s.channels < 1)
    throw InputError(path, "is not a 2D image (" + std::to_string(s.width) + "x" + std::to_string(s.height) + "x" +
                               std::to_string(s.depth) + ", " + std::to_string(s.channels) + " channels)");
  // Level 0 grows as its rows are read (so a header claiming more rows than the file holds fails
  // at the first missing chunk, not after the whole image is zero-filled), converted from one
  // chunk of float rows for non-8-bit sources. In double: 2^31 · 2^31 · 4 does not fit 64 bits.
  const std::uint32_t channels = static_cast<std::uint32_t>(std::min(s.channels, 4));
  const std::size_t value_size = s.is_uint8 ? 1 : sizeof(float);
  const double row_values = static_cast<double>(s.width) * channels;
  const double chunk =
      image_io::chunk_read_bytes(s, static_cast<std::size_t>(row_values) * value_size, kReadChunkBytes);
  image_io::require_read_memory(path, s, static_cast<double>(s.height) * row_values + chunk, max_bytes);
  Image8 img;
  img.width = static_cast<std::uint64_t>(s.width);
  img.height = static_cast<std::uint64_t>(s.height);
  img.channels = channels;
  img.texels.reserve(static_cast<std::size_t>(img.width * img.height * img.channels));  // address space, not pages
  const int c = static_cast<int>(channels);
  const image_io::OnDamage on_damage = accept_damaged ? image_io::OnDamage::read_on : image_io::OnDamage::stop;
  image_io::ReadStatus status;
  if (s.is_uint8) {
    status = in.read_chunked<std::uint8_t>(c, kReadChunkBytes, on_damage, [&](int y0, int y1, const std::uint8_t* v) {
      img.texels.insert(img.texels.end(), v, v + static_cast<std::size_t>(y1 - y0) * img.width * channels);
    });
  } else {
    const bool linear_source = s.is_float;
    status = in.read_chunked<float>(c, kReadChunkBytes, on_damage, [&](int y0, int y1, const float* v) {
      const std::size_t n = static_cast<std::size_t>(y1 - y0) * img.width * channels;
      img.texels.resize(img.texels.size() + n);
      std::uint8_t* out = img.texels.data() + img.texels.size() - n;
      for (std::size_t i = 0; i < n; ++i) {
        const auto ch = static_cast<std::uint32_t>(i % channels);
        float x = std::isfinite(v[i]) ? std::clamp(v[i], 0.0f, 1.0f) : 0.0f;
        if (linear_source && transfer == Transfer::srgb && is_colour(ch, channels)) x = linear_to_srgb(x);
        out[i] = quantise(x);
      }
    });
  }
  if (status == image_io::ReadStatus::failed) throw InputError(path, "cannot read the image: " + in.error());
  if (status == image_io::ReadStatus::ok_with_error && !accept_damaged)
    throw InputError(path, "is damaged: " + in.error() + " (the first " +
                               std::to_string(img.texels.size() / (img.width * channels)) + " of " +
                               std::to_string(img.height) +
                               " rows read cleanly; the reader fills what it cannot decode, and "
                               "--accept-damaged builds from that)");
  return img;
}

void write_image8(const std::string& path, const Image8& image) {
  const auto r = image_io::write_file(path, static_cast<int>(image.width), static_cast<int>(image.height),
                                      static_cast<int>(image.channels), image_io::PixelType::u8, image.texels.data(),
                                      /*unassociated_alpha=*/true);
  if (r.status == image_io::WriteStatus::cannot_create)
    throw InputError(path, "cannot write an image of this type: " + r.error);
  if (r.status == image_io::WriteStatus::failed) throw InputError(path, "cannot write the image: " + r.error);
}

std::vector<Image8> build_mip_chain(const Image8& level0, Transfer transfer, std::uint32_t levels) {
  std::vector<Image8> out;
  MipWalker walk(level0, transfer);
  for (std::uint32_t l = 0; l < levels; ++l) {
    if (l > 0) walk.advance();
    out.push_back(walk.current());
  }
  return out;
}

void extract_tile(const Image8& level, std::uint32_t tile, std::uint32_t border, std::uint64_t tx, std::uint64_t ty,
                  std::uint8_t* out) {
  const std::uint32_t side = tile + 2 * border, c = level.channels;
  const auto x0 = static_cast<std::int64_t>(tx * tile) - border, y0 = static_cast<std::int64_t>(ty * tile) - border;
  const auto wmax = static_cast<std::int64_t>(level.width) - 1, hmax = static_cast<std::int64_t>(level.height) - 1;
  for (std::uint32_t j = 0; j < side; ++j) {
    const auto y = static_cast<std::uint64_t>(std::clamp<std::int64_t>(y0 + j, 0, hmax));
    std::uint8_t* row = out + static_cast<std::size_t>(j) * side * c;
    for (std::uint32_t i = 0; i < side; ++i) {
      const auto x = static_cast<std::uint64_t>(std::clamp<std::int64_t>(x0 + i, 0, wmax));
      std::memcpy(row + static_cast<std::size_t>(i) * c, level.at(x, y), c);
    }
  }
}

BuildResult build_store(const std::vector<std::string>& images, const BuildOptions& o, const std::string& out_path,
                        const ProgressFn& progress) {
  if (images.empty()) throw InputError("IMAGE", "at least one image (one per layer) is needed");
  if (images.size() > kMaxLayers) throw InputError("IMAGE", dec(images.size()) + " images; a store has at most " + dec(kMaxLayers) + " layers");
  auto per_layer = [&](std::size_t given, const char* opt) {
    if (given != 0 && given != 1 && given != images.size())
      throw InputError(opt, dec(given) + " values for " + dec(images.size()) + " images (give one, or one per image)");
  };
  per_layer(o.codecs.size(), "--codec");
  per_layer(o.transfers.size(), "--transfer");
  if (!o.layer_names.empty() && o.layer_names.size() != images.size())
    throw InputError("--layer-names", dec(o.layer_names.size()) + " names for " + dec(images.size()) + " images");

  StoreSpec spec;
  spec.tile = o.tile;
  spec.border = o.border;
  spec.levels = o.levels;
  const std::uint64_t memory = o.memory_limit_bytes != 0 ? o.memory_limit_bytes : usable_memory_bytes();
  // The mip walk needs more than the level-0 images: check it from the headers before reading any
  // (an image that does not open is left to read_image8, which names its problem in order).
  if (o.levels != 1) {
    std::vector<image_io::ImageSpec> headers;
    for (const std::string& path : images)
      if (auto in = image_io::ImageReader::open_file(path, true); in && in.spec().width > 0 && in.spec().height > 0)
        headers.push_back(in.spec());
    const auto [peak, at] = mip_walk_peak(headers);
    if (headers.size() == images.size() && peak > static_cast<double>(memory) &&
        std::max(headers[at].width, headers[at].height) > 1)
      throw InputError(images[at], fmt::format("the mip walk over {} layer(s) of {}x{} needs {:.1f} MiB when it reduces "
                                               "this one (every level 0, and level 1 in float and 8 bits of the "
                                               "layers reduced so far), more than the {:.1f} MiB available",
                                               images.size(), headers[at].width, headers[at].height,
                                               peak / 1048576.0, static_cast<double>(memory) / 1048576.0));
  }
  std::vector<Image8> level0;
  std::uint64_t used = 0;  // by the level-0 images read so far (at most `memory`)
  for (std::size_t i = 0; i < images.size(); ++i) {
    StoreLayerSpec L;
    if (o.layer_names.empty()) {
      L.name = utf8_prefix(fs::path(images[i]).stem().string(), kLayerNameBytes - 1);
      if (const std::string why = layer_name_problem(L.name); !why.empty())
        throw InputError(images[i], "its file name cannot name the layer (" + why + "): name the layers with --layer-names");
    } else {
      L.name = o.layer_names[i];
    }
    L.codec = o.codecs.empty() ? CodecSpec{CodecId::zstd, default_codec_param(CodecId::zstd)}
                               : o.codecs[o.codecs.size() == 1 ? 0 : i];
    L.transfer = o.transfers.empty() ? Transfer::srgb : o.transfers[o.transfers.size() == 1 ? 0 : i];
    level0.push_back(read_image8(images[i], L.transfer, memory - used, o.accept_damaged));
    used += level0.back().texels.size();
    L.channels = level0.back().channels;
    if (i > 0 && (level0[i].width != level0[0].width || level0[i].height != level0[0].height))
      throw InputError(images[i], dec(level0[i].width) + "x" + dec(level0[i].height) + " differs from " + images[0] + " (" +
                                      dec(level0[0].width) + "x" + dec(level0[0].height) + "): every layer has the same size");
    spec.layers.push_back(L);
  }
  spec.width = level0[0].width;
  spec.height = level0[0].height;

  StoreWriter writer(out_path, spec);
  const Geometry& g = writer.geometry();
  std::vector<MipWalker> walkers;
  for (std::size_t i = 0; i < level0.size(); ++i) walkers.emplace_back(std::move(level0[i]), spec.layers[i].transfer);
  level0.clear();

  const std::uint64_t total = g.tile_count();
  std::uint64_t done = 0;
  for (std::uint32_t l = 0; l < g.levels; ++l) {
    if (l > 0)
      for (auto& w : walkers) w.advance();
    const std::uint64_t cols = g.cols[l], tiles = cols * g.rows[l];
    // Records go in (level, y, x, layer) order: the layers of one tile sit side by side on disk.
    encode_in_order(
        writer, tiles, o.threads,
        [&](std::uint64_t i, std::vector<EncodedTile>& out) {
          const std::uint64_t x = i % cols, y = i / cols;
          for (std::uint32_t layer = 0; layer < g.layers; ++layer) {
            std::vector<std::uint8_t> texels(writer.tile_bytes(layer));
            extract_tile(walkers[layer].current(), g.tile, g.border, x, y, texels.data());
            out.push_back(writer.encode(TileKey(layer, l, static_cast<std::int64_t>(x), static_cast<std::int64_t>(y)), texels.data()));
          }
        },
        [&](double f) {
          if (progress) progress((static_cast<double>(done) + f * static_cast<double>(tiles * g.layers)) / static_cast<double>(total));
        });
    done += tiles * g.layers;
  }
  writer.commit();
  BuildResult r;
  r.tiles = total;
  r.file_bytes = writer.header().file_bytes;
  r.stored_bytes = writer.stored_bytes();
  r.decoded_bytes = writer.decoded_bytes();
  return r;
}

}  // namespace vtsim
