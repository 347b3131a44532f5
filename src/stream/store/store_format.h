#pragma once
// The on-disk tile store, version 1 (docs/store-format.md is the byte-level spec).
//
// A store is one file: a 4 KiB header block, an index with one fixed 32-byte entry per tile, then
// tile records each starting at a 4 KiB-aligned offset and padded with zeros to the next 4 KiB
// boundary, so a tile is exactly one aligned O_DIRECT read (Yao 2007 §4-3: unbuffered async IO,
// files laid out in whole disk clusters). Everything is little-endian with fixed-width fields at
// explicit offsets; nothing is memcpy'd from a struct.
//
// This header holds the layout constants, the texture geometry shared by the writer and the
// reader (level sizes under ceil halving, tile grids, the O(1) index slot of a TileKey), and the
// little-endian field helpers.
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "core/tile_key.h"

namespace vtsim::store {

// Decimal text of a count, for the store's error messages (reader and writer).
inline std::string dec(std::uint64_t v) { return std::to_string(v); }

// Why `name` cannot be a layer name (empty when it can): at most kLayerNameBytes − 1 bytes of
// UTF-8 without control characters, as it is printed by `store info` and written into JSON.
std::string layer_name_problem(std::string_view name);

// ---- layout constants (docs/store-format.md §2) ------------------------------------------------
inline constexpr std::array<std::uint8_t, 8> kMagic = {'V', 'T', 'S', 'T', 'O', 'R', 'E', 0};
inline constexpr std::uint32_t kVersionMajor = 1;  // incompatible layout changes bump this
inline constexpr std::uint32_t kVersionMinor = 0;  // compatible additions (readers ignore)
// The O_DIRECT unit: logical block size of every common disk and filesystem cluster size; all
// offsets and read sizes are multiples of it.
inline constexpr std::uint32_t kAlign = 4096;
inline constexpr std::size_t kHeaderBlockBytes = kAlign;    // header region lives in [0, 4096)
inline constexpr std::size_t kFixedHeaderBytes = 128;       // fixed part of the header
inline constexpr std::size_t kLayerDescBytes = 64;          // one per layer, after the fixed part
inline constexpr std::size_t kIndexEntryBytes = 32;         // one per tile
inline constexpr std::size_t kLayerNameBytes = 32;          // NUL-padded UTF-8, <= 31 bytes used

// Field offsets in the fixed header.
namespace hdr {
inline constexpr std::size_t magic = 0, version_major = 8, version_minor = 12, header_bytes = 16,
                             flags = 20, width = 24, height = 32, tile_size = 40, border = 44,
                             level_count = 48, layer_count = 52, alignment = 56, index_offset = 64,
                             index_bytes = 72, index_checksum = 80, data_offset = 88,
                             file_bytes = 96, tile_count = 104, header_checksum = 120;
}
// Field offsets in a layer descriptor.
namespace lay {
inline constexpr std::size_t name = 0, channels = 32, bits = 36, codec = 40, codec_param = 44,
                             transfer = 48;
}
// Field offsets in an index entry.
namespace ent {
inline constexpr std::size_t offset = 0, stored_bytes = 8, decoded_bytes = 12, checksum = 16,
                             codec = 24;
}

// Limits a reader enforces (and a writer refuses to exceed). Tile side T + 2B <= 8192 keeps one
// decoded 4-channel tile under 2^28 bytes (the u32 size fields hold it with room to spare).
inline constexpr std::uint32_t kMaxTileSize = 8192;
inline constexpr std::uint32_t kMaxBorder = 256;
inline constexpr std::uint32_t kMaxStoredSide = 8192;
inline constexpr std::uint32_t kMaxLayers = TileKey::kMaxLayers;  // 16
inline constexpr std::uint32_t kMaxChannels = 4;

enum class CodecId : std::uint32_t { raw = 0, zstd = 1, lz4 = 2, png = 3, jpeg = 4 };
inline constexpr std::uint32_t kCodecCount = 5;

// How 8-bit values of a layer encode light: sRGB layers (albedo) are filtered in linear light,
// linear layers (normals, heights, masks) as stored. Alpha (4th channel) is always linear.
enum class Transfer : std::uint32_t { linear = 0, srgb = 1 };

// ---- little-endian fields ----------------------------------------------------------------------
inline std::uint32_t load_u32(const std::uint8_t* p) {
  return std::uint32_t{p[0]} | (std::uint32_t{p[1]} << 8) | (std::uint32_t{p[2]} << 16) |
         (std::uint32_t{p[3]} << 24);
}
inline std::uint64_t load_u64(const std::uint8_t* p) {
  return std::uint64_t{load_u32(p)} | (std::uint64_t{load_u32(p + 4)} << 32);
}
inline void store_u32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
inline void store_u64(std::uint8_t* p, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}

inline constexpr std::uint64_t round_up(std::uint64_t v, std::uint64_t a) { return (v + a - 1) / a * a; }

// XXH64 (seed 0) of a byte range: the checksum of header, index and every tile record.
std::uint64_t checksum64(const void* data, std::size_t bytes);

// ---- texture geometry --------------------------------------------------------------------------
// Level l of a W x H texture is ceil(W / 2^l) x ceil(H / 2^l) texels (docs/architecture.md).
inline std::uint64_t level_extent(std::uint64_t extent0, std::uint32_t level) {
  return level >= 64 ? 1 : ((extent0 - 1) >> level) + 1;
}
// Levels down to 1 x 1: 1 + ceil(log2(max(W, H))).
inline std::uint32_t full_level_count(std::uint64_t width, std::uint64_t height) {
  std::uint64_t m = width > height ? width : height;
  std::uint32_t n = 1;
  while (m > 1) { m = (m + 1) / 2; ++n; }
  return n;
}

// Geometry of one store: every layer has the same W, H, T, B and levels; the index holds
// layer_count * tiles_per_layer entries ordered by (layer, level, y, x), so the slot of a key is
// arithmetic (O(1), no search).
struct Geometry {
  std::uint64_t width = 0, height = 0;  // level 0, texels
  std::uint32_t tile = 0;               // payload side T, texels
  std::uint32_t border = 0;             // border B, texels; stored side is T + 2B
  std::uint32_t levels = 0;             // level 0 .. levels-1
  std::uint32_t layers = 0;
  std::vector<std::uint64_t> level_base;  // first slot of each level within a layer
  std::vector<std::uint64_t> cols, rows;  // tiles per level, x and y
  std::uint64_t tiles_per_layer = 0;

  static Geometry make(std::uint64_t width, std::uint64_t height, std::uint32_t tile,
                       std::uint32_t border, std::uint32_t levels, std::uint32_t layers) {
    Geometry g;
    g.width = width; g.height = height; g.tile = tile; g.border = border;
    g.levels = levels; g.layers = layers;
    for (std::uint32_t l = 0; l < levels; ++l) {
      g.level_base.push_back(g.tiles_per_layer);
      g.cols.push_back((level_extent(width, l) + tile - 1) / tile);
      g.rows.push_back((level_extent(height, l) + tile - 1) / tile);
      g.tiles_per_layer += g.cols.back() * g.rows.back();
    }
    return g;
  }
  std::uint32_t stored_side() const { return tile + 2 * border; }
  std::uint64_t level_width(std::uint32_t l) const { return level_extent(width, l); }
  std::uint64_t level_height(std::uint32_t l) const { return level_extent(height, l); }
  std::uint64_t tile_count() const { return tiles_per_layer * layers; }
  bool contains(TileKey k) const {
    return k.layer() < layers && k.level() < levels &&
           static_cast<std::uint64_t>(k.x()) < cols[k.level()] &&
           static_cast<std::uint64_t>(k.y()) < rows[k.level()];
  }
  // Index slot of a key the caller has checked with contains().
  std::uint64_t slot(TileKey k) const {
    return k.layer() * tiles_per_layer + level_base[k.level()] +
           static_cast<std::uint64_t>(k.y()) * cols[k.level()] + static_cast<std::uint64_t>(k.x());
  }
  // Inverse of slot().
  TileKey key_of_slot(std::uint64_t s) const {
    const auto layer = static_cast<std::uint32_t>(s / tiles_per_layer);
    std::uint64_t r = s % tiles_per_layer;
    std::uint32_t l = 0;
    while (l + 1 < levels && level_base[l + 1] <= r) ++l;
    r -= level_base[l];
    return TileKey(layer, l, static_cast<std::int64_t>(r % cols[l]), static_cast<std::int64_t>(r / cols[l]));
  }
};

// "layer 1 level 3 tile (4, 7)": how errors name a tile.
std::string describe(TileKey k);

// ---- parsed header and index -------------------------------------------------------------------
struct LayerInfo {
  std::string name;              // <= 31 bytes of UTF-8
  std::uint32_t channels = 0;    // 1..4, interleaved
  std::uint32_t bits = 8;        // bits per channel; 8 in version 1
  CodecId codec = CodecId::raw;
  std::int32_t codec_param = 0;  // as encoded (zstd level, JPEG quality...); informational
  Transfer transfer = Transfer::linear;

  std::uint32_t texel_bytes() const { return channels * bits / 8; }
};

struct StoreHeader {
  std::uint32_t version_major = kVersionMajor, version_minor = kVersionMinor;
  Geometry geom;
  std::vector<LayerInfo> layers;
  std::uint64_t index_offset = 0;    // bytes; multiple of kAlign
  std::uint64_t index_bytes = 0;     // tile_count * kIndexEntryBytes
  std::uint64_t index_checksum = 0;  // XXH64 of the index bytes
  std::uint64_t data_offset = 0;     // first byte a record may use; multiple of kAlign
  std::uint64_t file_bytes = 0;      // the whole file; multiple of kAlign
  // What the reader repaired rather than refused (a layer name cut inside a UTF-8 character by an
  // old builder: the partial bytes dropped), each naming the file and field. Not in the file.
  std::vector<std::string> warnings;

  // Decoded bytes of one tile of a layer: (T + 2B)^2 * channels.
  std::uint32_t tile_bytes(std::uint32_t layer) const {
    return geom.stored_side() * geom.stored_side() * layers[layer].texel_bytes();
  }
};

// One index entry: where a tile's record is and how to check it.
struct IndexEntry {
  std::uint64_t offset = 0;         // bytes from the file start; multiple of kAlign
  std::uint32_t stored_bytes = 0;   // payload bytes (record is padded to a multiple of kAlign)
  std::uint32_t decoded_bytes = 0;  // (T + 2B)^2 * channels
  std::uint64_t checksum = 0;       // XXH64 of the stored_bytes payload bytes
  CodecId codec = CodecId::raw;     // the layer's codec, or raw where it did not shrink the tile
};

// Serialise the header block (kHeaderBlockBytes, header checksum filled in) and index entries.
std::vector<std::uint8_t> encode_header(const StoreHeader& h);
void encode_index_entry(const IndexEntry& e, std::uint8_t* out);

}  // namespace vtsim::store
