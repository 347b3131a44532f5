#include "stream/store/tile_store.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>
#include <system_error>

#include "core/error.h"
#include "core/utf8.h"
#include "stream/store/i_codec.h"

namespace vtsim {

using namespace store;

namespace {

std::string field(const std::string& path, const char* name) { return path + ": header field '" + name + "'"; }

}  // namespace

StoreHeader parse_store_header(const std::string& path, const std::uint8_t* b, std::size_t size,
                               std::uint64_t file_size) {
  if (size < kFixedHeaderBytes)
    throw InputError(path + ": header", "truncated: the file has " + dec(size) + " bytes, a store header needs " +
                                            dec(kFixedHeaderBytes));
  if (std::memcmp(b + hdr::magic, kMagic.data(), kMagic.size()) != 0)
    throw InputError(field(path, "magic"), "not a vtsim tile store (bad magic; expected \"VTSTORE\\0\")");
  StoreHeader h;
  h.version_major = load_u32(b + hdr::version_major);
  h.version_minor = load_u32(b + hdr::version_minor);
  if (h.version_major != kVersionMajor)
    throw InputError(field(path, "version_major"), "format version " + dec(h.version_major) + "." + dec(h.version_minor) +
                                                       " is not supported (this reader reads " + dec(kVersionMajor) + ".x)");
  const std::uint32_t layer_count = load_u32(b + hdr::layer_count);
  if (layer_count < 1 || layer_count > kMaxLayers)
    throw InputError(field(path, "layer_count"), dec(layer_count) + " is out of range 1.." + dec(kMaxLayers));
  const std::uint32_t header_bytes = load_u32(b + hdr::header_bytes);
  const std::size_t need = kFixedHeaderBytes + kLayerDescBytes * layer_count;
  if (header_bytes < need || header_bytes > kHeaderBlockBytes)
    throw InputError(field(path, "header_bytes"), dec(header_bytes) + " is out of range " + dec(need) + ".." +
                                                      dec(kHeaderBlockBytes) + " for " + dec(layer_count) + " layers");
  if (size < header_bytes)
    throw InputError(path + ": header", "truncated: the file has " + dec(size) + " bytes, the header needs " + dec(header_bytes));
  {
    std::vector<std::uint8_t> copy(b, b + header_bytes);
    std::memset(copy.data() + hdr::header_checksum, 0, 8);
    const std::uint64_t want = load_u64(b + hdr::header_checksum);
    if (checksum64(copy.data(), copy.size()) != want)
      throw InputError(field(path, "header_checksum"), "mismatch: the header is corrupt");
  }
  if (load_u32(b + hdr::flags) != 0)
    throw InputError(field(path, "flags"), fmt::format("unknown flags {:#x}", load_u32(b + hdr::flags)) + " (none are defined in 1.x)");
  if (load_u32(b + hdr::alignment) != kAlign)
    throw InputError(field(path, "alignment"), dec(load_u32(b + hdr::alignment)) + " (version 1 requires " + dec(kAlign) + ")");

  const std::uint64_t width = load_u64(b + hdr::width), height = load_u64(b + hdr::height);
  const std::uint32_t tile = load_u32(b + hdr::tile_size), border = load_u32(b + hdr::border);
  const std::uint32_t levels = load_u32(b + hdr::level_count);
  if (tile < 1 || tile > kMaxTileSize)
    throw InputError(field(path, "tile_size"), dec(tile) + " is out of range 1.." + dec(kMaxTileSize));
  if (border > kMaxBorder || tile + 2 * border > kMaxStoredSide)
    throw InputError(field(path, "border"), dec(border) + " is out of range (border <= " + dec(kMaxBorder) +
                                                ", tile + 2*border <= " + dec(kMaxStoredSide) + ")");
  const std::uint64_t max_extent = static_cast<std::uint64_t>(TileKey::kMaxCoord + 1) * tile;
  if (width < 1 || width > max_extent)
    throw InputError(field(path, "width"), dec(width) + " is out of range 1.." + dec(max_extent));
  if (height < 1 || height > max_extent)
    throw InputError(field(path, "height"), dec(height) + " is out of range 1.." + dec(max_extent));
  const std::uint32_t full = full_level_count(width, height);
  if (levels < 1 || levels > full || levels > TileKey::kMaxLevels)
    throw InputError(field(path, "level_count"), dec(levels) + " is out of range 1.." + dec(std::min(full, TileKey::kMaxLevels)));
  h.geom = Geometry::make(width, height, tile, border, levels, layer_count);

  for (std::uint32_t i = 0; i < layer_count; ++i) {
    const std::uint8_t* d = b + kFixedHeaderBytes + i * kLayerDescBytes;
    const std::string where = path + ": layer " + dec(i) + " field ";
    LayerInfo L;
    const void* nul = std::memchr(d + lay::name, 0, kLayerNameBytes);
    if (!nul) throw InputError(where + "'name'", "is not NUL-terminated within 32 bytes");
    L.name.assign(reinterpret_cast<const char*>(d + lay::name), static_cast<const std::uint8_t*>(nul) - (d + lay::name));
    // Builders before names were checked cut a default name at byte 31, maybe inside a character.
    if (const std::size_t kept = utf8_without_cut_end(L.name); kept != L.name.size()) {
      h.warnings.push_back(where + "'name': " + dec(L.name.size() - kept) +
                           " trailing byte(s) of a character cut by the builder dropped (read as '" + L.name.substr(0, kept) + "')");
      L.name.resize(kept);
    }
    if (const std::string why = layer_name_problem(L.name); !why.empty()) throw InputError(where + "'name'", why);
    L.channels = load_u32(d + lay::channels);
    if (L.channels < 1 || L.channels > kMaxChannels)
      throw InputError(where + "'channels'", dec(L.channels) + " is out of range 1.." + dec(kMaxChannels));
    L.bits = load_u32(d + lay::bits);
    if (L.bits != 8) throw InputError(where + "'bits'", dec(L.bits) + " (version 1 stores 8 bits per channel)");
    const std::uint32_t codec = load_u32(d + lay::codec);
    if (codec >= kCodecCount) throw InputError(where + "'codec'", "unknown codec id " + dec(codec));
    L.codec = static_cast<CodecId>(codec);
    if (!decoder_for(L.codec).supports_channels(static_cast<int>(L.channels)))
      throw InputError(where + "'codec'", std::string(codec_name(L.codec)) + " cannot store " + dec(L.channels) + " channels");
    L.codec_param = static_cast<std::int32_t>(load_u32(d + lay::codec_param));
    const std::uint32_t transfer = load_u32(d + lay::transfer);
    if (transfer > 1) throw InputError(where + "'transfer'", dec(transfer) + " is not 0 (linear) or 1 (sRGB)");
    L.transfer = static_cast<Transfer>(transfer);
    h.layers.push_back(std::move(L));
  }

  const std::uint64_t tile_count = load_u64(b + hdr::tile_count);
  if (tile_count != h.geom.tile_count())
    throw InputError(field(path, "tile_count"), dec(tile_count) + " disagrees with the geometry (" + dec(h.geom.tile_count()) + " tiles)");
  h.file_bytes = load_u64(b + hdr::file_bytes);
  if (h.file_bytes % kAlign != 0)
    throw InputError(field(path, "file_bytes"), dec(h.file_bytes) + " is not a multiple of " + dec(kAlign));
  if (file_size < h.file_bytes)
    throw InputError(path, "truncated: the file has " + dec(file_size) + " bytes, its header (field 'file_bytes') says " + dec(h.file_bytes));
  if (file_size > h.file_bytes)
    throw InputError(field(path, "file_bytes"), "the file has " + dec(file_size - h.file_bytes) + " bytes past the " +
                                                    dec(h.file_bytes) + " its header records");
  h.index_offset = load_u64(b + hdr::index_offset);
  h.index_bytes = load_u64(b + hdr::index_bytes);
  h.index_checksum = load_u64(b + hdr::index_checksum);
  h.data_offset = load_u64(b + hdr::data_offset);
  if (h.index_offset % kAlign != 0 || h.index_offset < kHeaderBlockBytes)
    throw InputError(field(path, "index_offset"), dec(h.index_offset) + " is not a multiple of " + dec(kAlign) + " at or after the header block");
  if (h.index_offset >= h.file_bytes)
    throw InputError(field(path, "index_offset"), dec(h.index_offset) + " is past the end of the file (" + dec(h.file_bytes) + " bytes)");
  if (tile_count > h.file_bytes / kIndexEntryBytes || h.index_bytes != tile_count * kIndexEntryBytes)
    throw InputError(field(path, "index_bytes"), dec(h.index_bytes) + " does not hold " + dec(tile_count) + " entries of " + dec(kIndexEntryBytes) + " bytes");
  if (h.index_bytes > h.file_bytes - h.index_offset)
    throw InputError(field(path, "index_bytes"), "the index [" + dec(h.index_offset) + ", " + dec(h.index_offset + h.index_bytes) +
                                                     ") runs past the end of the file (" + dec(h.file_bytes) + " bytes)");
  if (h.data_offset % kAlign != 0 || h.data_offset < h.index_offset + h.index_bytes || h.data_offset > h.file_bytes)
    throw InputError(field(path, "data_offset"), dec(h.data_offset) + " is not a multiple of " + dec(kAlign) +
                                                     " between the end of the index and the end of the file");
  return h;
}

TileStore TileStore::open(const std::string& path) {
  TileStore s;
  s.path_ = path;
  s.file_ = open_for_read(path, false).file;
  const std::uint64_t file_size = s.file_.size();
  std::vector<std::uint8_t> block(static_cast<std::size_t>(std::min<std::uint64_t>(file_size, kHeaderBlockBytes)));
  try {
    if (s.file_.pread_full(block.data(), block.size(), 0) != block.size())
      throw InputError(path + ": header", "short read");
  } catch (const std::system_error& e) {
    throw InputError(path + ": header", e.what());
  }
  s.header_ = parse_store_header(path, block.data(), block.size(), file_size);
  const StoreHeader& h = s.header_;
  const Geometry& g = h.geom;

  std::vector<std::uint8_t> raw(static_cast<std::size_t>(h.index_bytes));
  try {
    if (s.file_.pread_full(raw.data(), raw.size(), h.index_offset) != raw.size())
      throw InputError(path + ": index", "truncated");
  } catch (const std::system_error& e) {
    throw InputError(path + ": index", e.what());
  }
  if (checksum64(raw.data(), raw.size()) != h.index_checksum)
    throw InputError(field(path, "index_checksum"), "mismatch: the index is corrupt");

  const std::uint64_t n = g.tile_count();
  s.index_.resize(static_cast<std::size_t>(n));
  struct Span {
    std::uint64_t begin, end, slot;
  };
  std::vector<Span> spans(static_cast<std::size_t>(n));
  for (std::uint64_t i = 0; i < n; ++i) {
    const std::uint8_t* p = raw.data() + i * kIndexEntryBytes;
    IndexEntry e;
    e.offset = load_u64(p + ent::offset);
    e.stored_bytes = load_u32(p + ent::stored_bytes);
    e.decoded_bytes = load_u32(p + ent::decoded_bytes);
    e.checksum = load_u64(p + ent::checksum);
    const std::uint32_t codec = load_u32(p + ent::codec);
    const TileKey k = g.key_of_slot(i);
    // Built only for an error: open() checks millions of entries in a large store.
    const auto where = [&] { return path + ": index entry " + dec(i) + " (" + describe(k) + ") field "; };
    const std::uint32_t want = h.tile_bytes(k.layer());
    if (e.decoded_bytes != want)
      throw InputError(where() + "'decoded_bytes'", dec(e.decoded_bytes) + ", the tile holds " + dec(want) + " bytes");
    if (e.stored_bytes < 1 || e.stored_bytes > want)
      throw InputError(where() + "'stored_bytes'", dec(e.stored_bytes) + " is out of range 1.." + dec(want));
    const CodecId layer_codec = h.layers[k.layer()].codec;
    if (codec != static_cast<std::uint32_t>(layer_codec) && codec != static_cast<std::uint32_t>(CodecId::raw))
      throw InputError(where() + "'codec'", dec(codec) + " is neither the layer's codec (" + std::string(codec_name(layer_codec)) + ") nor raw");
    e.codec = static_cast<CodecId>(codec);
    if (e.codec == CodecId::raw && e.stored_bytes != want)
      throw InputError(where() + "'stored_bytes'", dec(e.stored_bytes) + " for a raw tile of " + dec(want) + " bytes");
    if (e.offset % kAlign != 0)
      throw InputError(where() + "'offset'", dec(e.offset) + " is not a multiple of " + dec(kAlign));
    const std::uint64_t end = e.offset + round_up(e.stored_bytes, kAlign);
    if (e.offset < h.data_offset || e.offset > h.file_bytes || end > h.file_bytes)
      throw InputError(where() + "'offset'", "record [" + dec(e.offset) + ", " + dec(end) + ") is outside the data region [" +
                                               dec(h.data_offset) + ", " + dec(h.file_bytes) + ")");
    s.index_[i] = e;
    spans[i] = {e.offset, end, i};
  }
  std::sort(spans.begin(), spans.end(), [](const Span& a, const Span& b) { return a.begin < b.begin; });
  for (std::size_t i = 1; i < spans.size(); ++i)
    if (spans[i].begin < spans[i - 1].end)
      throw InputError(path + ": index entry " + dec(spans[i].slot) + " (" + describe(g.key_of_slot(spans[i].slot)) + ") field 'offset'",
                       "record at " + dec(spans[i].begin) + " overlaps the record of " + describe(g.key_of_slot(spans[i - 1].slot)) +
                           " [" + dec(spans[i - 1].begin) + ", " + dec(spans[i - 1].end) + ")");
  return s;
}

TileLocation TileStore::locate(TileKey k) const {
  if (!contains(k)) throw InputError(path_ + ": " + describe(k), "is outside the store");
  const IndexEntry& e = index_[header_.geom.slot(k)];
  return {e.offset, e.stored_bytes, static_cast<std::uint32_t>(round_up(e.stored_bytes, kAlign)), e.checksum, e.decoded_bytes};
}

void TileStore::verify_and_decode(TileKey k, const std::uint8_t* record, std::size_t size, std::uint8_t* out,
                                  std::size_t out_size) const {
  if (!contains(k)) throw InputError(path_ + ": " + describe(k), "is outside the store");
  const IndexEntry& e = index_[header_.geom.slot(k)];
  const auto where = [&] { return path_ + ": " + describe(k); };  // only for an error: every read passes here
  if (size < e.stored_bytes)
    throw InputError(where(), "record has " + dec(size) + " bytes, the index says " + dec(e.stored_bytes));
  if (out_size < e.decoded_bytes)
    throw InputError(where(), "output buffer of " + dec(out_size) + " bytes is smaller than the tile (" + dec(e.decoded_bytes) + ")");
  if (checksum64(record, e.stored_bytes) != e.checksum) throw InputError(where(), "checksum mismatch: the record is corrupt");
  const int side = static_cast<int>(header_.geom.stored_side());
  try {
    decoder_for(e.codec).decode(record, e.stored_bytes, side, side, static_cast<int>(header_.layers[k.layer()].channels), out);
  } catch (const CodecError& err) {
    throw InputError(where(), std::string("does not decode: ") + err.what());
  }
}

void TileStore::read_tile(TileKey k, AlignedBuffer& scratch, std::uint8_t* out, std::size_t out_size) const {
  const TileLocation loc = locate(k);
  scratch.reserve(loc.read_bytes);
  std::size_t got = 0;
  try {
    got = file_.pread_full(scratch.data(), loc.read_bytes, loc.offset);
  } catch (const std::system_error& e) {
    throw InputError(path_ + ": " + describe(k), e.what());
  }
  if (got < loc.stored_bytes)
    throw InputError(path_ + ": " + describe(k), "short read: " + dec(got) + " of " + dec(loc.stored_bytes) + " bytes (file truncated?)");
  verify_and_decode(k, scratch.data(), got, out, out_size);
}

std::vector<TileStore::LayerTotals> TileStore::totals() const {
  std::vector<LayerTotals> t(header_.geom.layers);
  for (std::size_t i = 0; i < index_.size(); ++i) {
    LayerTotals& L = t[i / header_.geom.tiles_per_layer];
    ++L.tiles;
    L.stored_bytes += index_[i].stored_bytes;
    L.read_bytes += round_up(index_[i].stored_bytes, kAlign);
    L.decoded_bytes += index_[i].decoded_bytes;
  }
  return t;
}

}  // namespace vtsim
