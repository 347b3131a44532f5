#pragma once
// The tile store reader (format: store_format.h, docs/store-format.md).
//
// TileStore::open validates the whole header and index up front — magic, version, every field's
// range, header and index checksums, every record's alignment, bounds and non-overlap — and
// throws InputError naming the file and the field or tile. After that, lookups cannot fail on a
// tile inside the texture, and a record read later is checked by its own checksum.
//
// The IO pool drives it as: locate(key) -> one aligned pread of read_bytes at offset into an
// AlignedBuffer (O_DIRECT file from open_for_read) -> verify_and_decode(key, buf, stored_bytes,
// out) on a decode worker. read_tile() does both synchronously for tools and tests.
//
// Complexity: open is O(tiles log tiles) (the overlap check sorts offsets); locate and
// stored_bytes are O(1) (arithmetic slot, no search); memory is ~32 bytes per tile.
// Thread-safety: open once on one thread; afterwards every const member may be called from any
// number of threads at once (the index is immutable; reads use pread on a shared descriptor).
// Nothing invalidates a TileStore but moving from it; the file must not be rewritten under it.
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/tile_key.h"
#include "stream/store/aligned_io.h"
#include "stream/store/store_format.h"

namespace vtsim {

struct TileLocation {
  std::uint64_t offset = 0;        // bytes from the file start; multiple of 4096
  std::uint32_t stored_bytes = 0;  // payload bytes to verify and decode
  std::uint32_t read_bytes = 0;    // stored_bytes rounded up to 4096: the O_DIRECT read size
  std::uint64_t checksum = 0;      // XXH64 of the payload
  std::uint32_t decoded_bytes = 0; // bytes decode writes: (T + 2B)^2 * channels
};

class TileStore {
 public:
  // Opens and validates `path`. Throws InputError("path: <field or tile>", what) on any defect.
  static TileStore open(const std::string& path);

  const std::string& path() const { return path_; }
  const store::StoreHeader& header() const { return header_; }
  const store::Geometry& geometry() const { return header_.geom; }
  const store::LayerInfo& layer(std::uint32_t i) const { return header_.layers[i]; }
  std::uint32_t layer_count() const { return header_.geom.layers; }
  std::uint32_t level_count() const { return header_.geom.levels; }
  std::uint32_t tile_bytes(std::uint32_t layer) const { return header_.tile_bytes(layer); }

  bool contains(TileKey k) const { return header_.geom.contains(k); }
  // Where a tile's record is. Throws InputError naming the tile if it is outside the texture.
  TileLocation locate(TileKey k) const;
  // Stored (compressed) payload bytes of a tile; 0 for a key outside the texture. The simulated
  // clock's "disk bytes per tile" (plus read_bytes for the aligned figure).
  std::uint32_t stored_bytes(TileKey k) const {
    return contains(k) ? index_[header_.geom.slot(k)].stored_bytes : 0;
  }
  // The whole index in slot order (layer, level, y, x); see store::Geometry::slot.
  std::span<const store::IndexEntry> index() const { return index_; }

  // Checks the record's checksum, then decodes it into out[0, tile_bytes(layer)). `record` holds
  // at least `size` bytes where size >= stored_bytes (a padded aligned read is fine). Throws
  // InputError("path: layer L level l tile (x, y)", ...) on a checksum mismatch or a payload that
  // does not decode to exactly the tile.
  void verify_and_decode(TileKey k, const std::uint8_t* record, std::size_t size, std::uint8_t* out,
                         std::size_t out_size) const;

  // Synchronous read through the store's own buffered descriptor: pread into `scratch` (grown as
  // needed), then verify_and_decode into `out` (tile_bytes(layer) bytes). Throws InputError on a
  // short read, IO error, checksum or decode failure, naming the tile.
  void read_tile(TileKey k, AlignedBuffer& scratch, std::uint8_t* out, std::size_t out_size) const;

  // Totals over the index: payload bytes, aligned read bytes and decoded bytes (per layer).
  struct LayerTotals {
    std::uint64_t tiles = 0, stored_bytes = 0, read_bytes = 0, decoded_bytes = 0;
  };
  std::vector<LayerTotals> totals() const;

 private:
  std::string path_;
  store::StoreHeader header_;
  std::vector<store::IndexEntry> index_;
  ReadFile file_;
};

// Parses and validates a header block (>= kHeaderBlockBytes bytes or the whole file if shorter);
// `file_size` is the actual file size. Exposed for tests and tools. Throws InputError.
store::StoreHeader parse_store_header(const std::string& path, const std::uint8_t* bytes,
                                      std::size_t size, std::uint64_t file_size);

}  // namespace vtsim
