// Reading a source image for `vtsim store build` (read_image8: chunks of ~16 MiB of rows, level 0
// growing with them, docs/store-format.md §7) against the whole-image read it replaced, measured
// side by side in the same run: OpenImageIO's read of the whole image into one buffer
// (ImageReader::read), then the same per-value conversion to 8 bits. Both read the same file, from
// the page cache after the warm-up. Linear transfer on both sides, so the conversion is the same
// clamp-and-round; ratio = ours MB/s / whole-image MB/s of 8-bit output.
//   build/bench/bench_image_read [--quick] [--reps N] [--json FILE] [--filter exr]
// Memory is not timed here: the whole-image side holds a float copy of the image (4 bytes a value
// for non-8-bit sources) beside the output, ours one chunk (the params say how much).
#include <fmt/core.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/image_io.h"
#include "harness.h"
#include "stream/store/store_builder.h"

using namespace vtsim;
namespace fs = std::filesystem;

namespace {

// The pre-chunking read_image8 for linear transfer: the whole image in one read, then converted.
std::vector<std::uint8_t> read_whole(const std::string& path) {
  auto in = image_io::ImageReader::open_file(path, true);
  const image_io::ImageSpec& s = in.spec();
  const int c = std::min(s.channels, 4);
  const std::size_t n = static_cast<std::size_t>(s.width) * static_cast<std::size_t>(s.height) * c;
  std::vector<std::uint8_t> out(n);
  if (s.is_uint8) {
    in.read(c, image_io::PixelType::u8, out.data());
    return out;
  }
  std::vector<float> f(n);
  in.read(c, image_io::PixelType::f32, f.data());
  for (std::size_t i = 0; i < n; ++i) {
    const float v = std::isfinite(f[i]) ? std::clamp(f[i], 0.0f, 1.0f) : 0.0f;
    out[i] = static_cast<std::uint8_t>(v * 255.0f + 0.5f);
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  bench::Harness h("image_read", argc, argv, 7, 3);
  const int side = h.pick(4096, 2048);
  const int c = 3;
  h.param("image", fmt::format("{0}x{0}x{1}", side, c));
  const fs::path dir = fs::temp_directory_path() / fmt::format("vtsim-bench-image-read-{}", ::getpid());
  fs::create_directories(dir);
  // A smooth gradient with a little structure: compressible like a photo-ish texture, not a constant.
  const std::size_t n = static_cast<std::size_t>(side) * side * c;
  std::vector<float> f(n);
  std::vector<std::uint8_t> u(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t p = i / c, x = p % side, y = p / side;
    f[i] = static_cast<float>((x * (i % c + 1) + y * 3 + (x ^ y) % 17) % 1024) / 1023.0f;
    u[i] = static_cast<std::uint8_t>(f[i] * 255.0f + 0.5f);
  }
  struct Source {
    const char* name;
    image_io::PixelType type;
  };
  for (const Source src : {Source{"exr", image_io::PixelType::f32}, Source{"tif", image_io::PixelType::u8},
                           Source{"png", image_io::PixelType::u8}}) {
    const std::string path = (dir / (std::string("source.") + src.name)).string();
    const void* px = src.type == image_io::PixelType::f32 ? static_cast<const void*>(f.data()) : u.data();
    if (image_io::write_file(path, side, side, c, src.type, px, true).status != image_io::WriteStatus::ok) {
      fmt::print(stderr, "bench_image_read: cannot write {}\n", path);
      return 1;
    }
    const bool is_float = src.type == image_io::PixelType::f32;
    h.compare({.name = std::string("read_") + src.name,
               .metric = bench::Metric::kMBPerS,
               .work = static_cast<double>(n),
               .params = {{"format", src.name},
                          {"file_bytes", fs::file_size(path)},
                          {"whole_image_float_copy_bytes", is_float ? n * sizeof(float) : 0},
                          {"chunk_bytes_at_most", 16 << 20}},
               .target_ratio = 0},
              {"chunked", {}, [&] {
                 Image8 img = read_image8(path, store::Transfer::linear);
                 bench::do_not_optimize(img.texels.data());
               }},
              {"whole_image", {}, [&] {
                 std::vector<std::uint8_t> out = read_whole(path);
                 bench::do_not_optimize(out.data());
               }});
  }
  fs::remove_all(dir);
  return h.finish();
}
