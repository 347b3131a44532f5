// Tile stores (.vts, docs/store-format.md): the header, layer table and index are validated at
// open; then every tile (the first 4,096 in slot order) is read, checksummed and decoded as the
// real clock reads them. A store that opens must never crash a read: a bad tile is an InputError.
#include <algorithm>
#include <vector>

#include "fuzz_targets.h"
#include "stream/store/aligned_io.h"
#include "stream/store/tile_store.h"

namespace vtsim::fuzz {

void store(const std::uint8_t* data, std::size_t size) {
  const std::string path = input_file(data, size, "vts");
  expect_accept_or_reject("store", [&] {
    const TileStore s = TileStore::open(path);
    (void)s.totals();
    AlignedBuffer scratch;
    std::vector<std::uint8_t> out;
    const std::size_t n = std::min<std::size_t>(s.index().size(), 4096);
    for (std::size_t i = 0; i < n; ++i) {
      const TileKey k = s.geometry().key_of_slot(i);
      out.resize(s.tile_bytes(k.layer()));
      expect_accept_or_reject("store", [&] { s.read_tile(k, scratch, out.data(), out.size()); });
    }
  });
}

}  // namespace vtsim::fuzz
