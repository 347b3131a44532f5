#include "stream/store/store_format.h"

#define XXH_INLINE_ALL
#include <xxhash.h>

#include <algorithm>

#include "core/utf8.h"

namespace vtsim::store {

// XXH64 rather than CRC32C: a 64-bit check (collisions 2^-64, not 2^-32, over millions of tiles),
// ~10 GB/s per core in portable C with no CPU-specific path, and a published spec and a Debian
// library (libxxhash) so a second implementation can check a store bit for bit.
std::uint64_t checksum64(const void* data, std::size_t bytes) { return XXH64(data, bytes, 0); }

std::string layer_name_problem(std::string_view name) {
  if (name.size() >= kLayerNameBytes || name.find('\0') != std::string_view::npos)
    return "a name is at most " + dec(kLayerNameBytes - 1) + " bytes without NUL";
  if (const std::size_t bad = find_invalid_utf8(name); bad != std::string_view::npos)
    return "byte " + dec(bad) + " of the name is not UTF-8";
  for (std::size_t i = 0; i < name.size(); ++i)
    if (static_cast<unsigned char>(name[i]) < 0x20 || name[i] == 0x7F)
      return "byte " + dec(i) + " of the name is a control character";
  return {};
}

std::string describe(TileKey k) {
  return "layer " + std::to_string(k.layer()) + " level " + std::to_string(k.level()) + " tile (" +
         std::to_string(k.x()) + ", " + std::to_string(k.y()) + ")";
}

std::vector<std::uint8_t> encode_header(const StoreHeader& h) {
  std::vector<std::uint8_t> b(kHeaderBlockBytes, 0);
  std::memcpy(b.data() + hdr::magic, kMagic.data(), kMagic.size());
  store_u32(&b[hdr::version_major], h.version_major);
  store_u32(&b[hdr::version_minor], h.version_minor);
  const auto header_bytes = static_cast<std::uint32_t>(kFixedHeaderBytes + kLayerDescBytes * h.layers.size());
  store_u32(&b[hdr::header_bytes], header_bytes);
  store_u32(&b[hdr::flags], 0);
  store_u64(&b[hdr::width], h.geom.width);
  store_u64(&b[hdr::height], h.geom.height);
  store_u32(&b[hdr::tile_size], h.geom.tile);
  store_u32(&b[hdr::border], h.geom.border);
  store_u32(&b[hdr::level_count], h.geom.levels);
  store_u32(&b[hdr::layer_count], static_cast<std::uint32_t>(h.layers.size()));
  store_u32(&b[hdr::alignment], kAlign);
  store_u64(&b[hdr::index_offset], h.index_offset);
  store_u64(&b[hdr::index_bytes], h.index_bytes);
  store_u64(&b[hdr::index_checksum], h.index_checksum);
  store_u64(&b[hdr::data_offset], h.data_offset);
  store_u64(&b[hdr::file_bytes], h.file_bytes);
  store_u64(&b[hdr::tile_count], h.geom.tile_count());
  for (std::size_t i = 0; i < h.layers.size(); ++i) {
    std::uint8_t* d = &b[kFixedHeaderBytes + i * kLayerDescBytes];
    const LayerInfo& L = h.layers[i];
    std::memcpy(d + lay::name, L.name.data(), std::min(L.name.size(), kLayerNameBytes - 1));
    store_u32(d + lay::channels, L.channels);
    store_u32(d + lay::bits, L.bits);
    store_u32(d + lay::codec, static_cast<std::uint32_t>(L.codec));
    store_u32(d + lay::codec_param, static_cast<std::uint32_t>(L.codec_param));
    store_u32(d + lay::transfer, static_cast<std::uint32_t>(L.transfer));
  }
  // The checksum covers [0, header_bytes) with its own 8 bytes read as zero.
  store_u64(&b[hdr::header_checksum], checksum64(b.data(), header_bytes));
  return b;
}

void encode_index_entry(const IndexEntry& e, std::uint8_t* out) {
  std::memset(out, 0, kIndexEntryBytes);
  store_u64(out + ent::offset, e.offset);
  store_u32(out + ent::stored_bytes, e.stored_bytes);
  store_u32(out + ent::decoded_bytes, e.decoded_bytes);
  store_u64(out + ent::checksum, e.checksum);
  store_u32(out + ent::codec, static_cast<std::uint32_t>(e.codec));
}

}  // namespace vtsim::store
