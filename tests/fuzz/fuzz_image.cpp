// Images (through the OpenImageIO module, core/image_io.h), as a heightfield (scene.file) and as
// the layer of a store (`vtsim store build`): the input is written as a .pnm (PBM/PGM/PPM, whose
// header alone sets size, channels and bit depth) and, when the first read accepts it, the store
// built from it must open and every tile (first 4,096) read back. The decoders themselves are
// OpenImageIO's; this target checks what vtsim does with what they return.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <vector>

#include "fuzz_targets.h"
#include "sim/scene_heightfield.h"
#include "stream/aligned_io.h"
#include "stream/store_builder.h"
#include "stream/tile_store.h"

namespace vtsim::fuzz {

void image(const std::uint8_t* data, std::size_t size) {
  const std::string path = input_file(data, size, "pnm");
  expect_accept_or_reject("image", [&] { (void)load_heightfield(path, 8.0, 1.0, 0.0, 0.0, 0.0, std::int64_t{1} << 20); });
  const std::string out = std::filesystem::path(path).replace_filename("built.vts").string();
  bool built = false;
  expect_accept_or_reject("image", [&] {
    BuildOptions o;
    o.tile = 8;
    o.border = 1;
    o.threads = 1;
    o.layer_names = {"albedo"};
    o.memory_limit_bytes = std::uint64_t{96} << 20;  // above the 64 MiB strip floor, far below libFuzzer's 2 GiB
    (void)build_store({path}, o, out);
    built = true;
  });
  if (!built) return;
  try {  // a store just built must open and read back: any error here is a finding
    const TileStore s = TileStore::open(out);
    AlignedBuffer scratch;
    std::vector<std::uint8_t> tile;
    const std::size_t n = std::min<std::size_t>(s.index().size(), 4096);
    for (std::size_t i = 0; i < n; ++i) {
      const TileKey k = s.geometry().key_of_slot(i);
      tile.resize(s.tile_bytes(k.layer()));
      s.read_tile(k, scratch, tile.data(), tile.size());
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vtsim fuzz image: the store built from the image does not read back: %s\n", e.what());
    std::abort();
  }
}

}  // namespace vtsim::fuzz
