// Images (through the OpenImageIO module, core/image_io.h), as a heightfield (scene.file) and as
// the layer of a store (`vtsim store build`): the input is written as a .tif, .png, .jpg, .exr,
// .jp2, .webp or .hdr when it starts with that format's signature (tiled TIFFs size OpenImageIO's
// read buffers by the tile in their header; the others claim a size before any data; JPEG 2000 and
// WebP readers decode the whole image), else as a .pnm (PBM/PGM/PPM, whose header alone sets size,
// channels and bit depth). When the first
// read accepts it, the store built from it must open and every tile (first 4,096) read back. The
// decoders themselves are OpenImageIO's and libtiff's; this target checks what vtsim does with what
// they return.
#include <algorithm>
#include <cstring>
#include <filesystem>
#include <vector>

#include "core/image_io.h"
#include "fuzz_targets.h"
#include "sim/view/scene_heightfield.h"
#include "stream/store/aligned_io.h"
#include "stream/store/store_builder.h"
#include "stream/store/tile_store.h"

namespace vtsim::fuzz {

// Above read_scratch_bytes' 64 MiB floor, far below libFuzzer's 2 GiB.
constexpr std::uint64_t kMemoryLimit = std::uint64_t{96} << 20;

void image(const std::uint8_t* data, std::size_t size) {
  auto starts = [&](const char* magic, std::size_t n) { return size >= n && std::memcmp(data, magic, n) == 0; };
  const char* ext = starts("II*\0", 4) || starts("MM\0*", 4)                ? "tif"
                    : starts("\x89PNG", 4)                                   ? "png"
                    : starts("\xFF\xD8\xFF", 3)                             ? "jpg"
                    : starts("v/1\x01", 4)                                   ? "exr"
                    : starts("\0\0\0\x0CjP  ", 8) || starts("\xFF\x4F\xFF\x51", 4) ? "jp2"
                    : starts("RIFF", 4) && size >= 12 && std::memcmp(data + 8, "WEBP", 4) == 0 ? "webp"
                    : starts("#?", 2)                                         ? "hdr"
                                                                              : "pnm";
  const std::string path = input_file(data, size, ext);
  expect_accept_or_reject("image", [&] {
    (void)load_heightfield(path, 8.0, 1.0, 0.0, 0.0, 0.0, std::int64_t{1} << 20, kMemoryLimit);
  });
  const std::string out = std::filesystem::path(path).replace_filename("built.vts").string();
  // The store build only for images of at most 2^18 pixels: a 14 × 603,105 PGM made a store of
  // 300,000 tiles (1.2 GB written) per input, the fuzzer's 10 s timeout. Larger images still go
  // through the heightfield read above and read_image8's limit check here.
  if (auto in = image_io::ImageReader::open_file(path, true);
      in && static_cast<double>(in.spec().width) * static_cast<double>(in.spec().height) > static_cast<double>(1 << 18)) {
    expect_accept_or_reject("image", [&] { (void)read_image8(path, store::Transfer::srgb, kMemoryLimit); });
    return;
  }
  bool built = false;
  expect_accept_or_reject("image", [&] {
    BuildOptions o;
    o.tile = 8;
    o.border = 1;
    o.threads = 1;
    o.layer_names = {"albedo"};
    o.memory_limit_bytes = kMemoryLimit;
    (void)build_store({path}, o, out);
    built = true;
  });
  if (!built) return;
  must_succeed("image", "reading back the store built from the image", [&] {
    const TileStore s = TileStore::open(out);
    AlignedBuffer scratch;
    std::vector<std::uint8_t> tile;
    const std::size_t n = std::min<std::size_t>(s.index().size(), 4096);
    for (std::size_t i = 0; i < n; ++i) {
      const TileKey k = s.geometry().key_of_slot(i);
      tile.resize(s.tile_bytes(k.layer()));
      s.read_tile(k, scratch, tile.data(), tile.size());
    }
  });
}

}  // namespace vtsim::fuzz
