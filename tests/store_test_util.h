#pragma once
// Helpers for the tile-store tests: a self-deleting temporary directory, whole-file IO, and
// small deterministic test images (no downloads, nothing checked in).
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/tile_key.h"
#include "stream/store/store_builder.h"

namespace vtsim::test {

struct TempDir {
  std::filesystem::path path;
  TempDir() {
    std::string t = (std::filesystem::temp_directory_path() / "vtsim-store-test-XXXXXX").string();
    if (!::mkdtemp(t.data())) throw std::runtime_error("mkdtemp failed");
    path = t;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  std::string file(const std::string& name) const { return (path / name).string(); }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
};

inline std::vector<std::uint8_t> read_bytes(const std::string& p) {
  std::ifstream f(p, std::ios::binary);
  return std::vector<std::uint8_t>(std::istreambuf_iterator<char>(f), {});
}
inline void write_bytes(const std::string& p, const std::vector<std::uint8_t>& b) {
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

// Smooth gradients plus a little hashed noise: every texel differs from its neighbours (so a
// border taken from the wrong place is caught) and the image still compresses.
inline Image8 make_image(std::uint64_t w, std::uint64_t h, std::uint32_t c, std::uint64_t seed = 1) {
  Image8 img;
  img.width = w;
  img.height = h;
  img.channels = c;
  img.texels.assign(static_cast<std::size_t>(w * h * c), std::uint8_t{0});
  for (std::uint64_t y = 0; y < h; ++y)
    for (std::uint64_t x = 0; x < w; ++x)
      for (std::uint32_t ch = 0; ch < c; ++ch) {
        const std::uint64_t n = mix64(seed ^ (x * 7919 + y * 104729 + ch * 15485863)) & 15;
        const std::uint64_t v = (ch % 2 == 0 ? x * 255 / w : y * 255 / h) / 2 + ((x + 3 * y) % 64) + n;
        img.texels[static_cast<std::size_t>((y * w + x) * c + ch)] = static_cast<std::uint8_t>(v > 255 ? 255 : v);
      }
  return img;
}

// Level texel (clamped to the level) of an image.
inline const std::uint8_t* clamped(const Image8& img, std::int64_t x, std::int64_t y) {
  const std::int64_t cx = x < 0 ? 0 : (x >= static_cast<std::int64_t>(img.width) ? static_cast<std::int64_t>(img.width) - 1 : x);
  const std::int64_t cy = y < 0 ? 0 : (y >= static_cast<std::int64_t>(img.height) ? static_cast<std::int64_t>(img.height) - 1 : y);
  return img.at(static_cast<std::uint64_t>(cx), static_cast<std::uint64_t>(cy));
}

// What build_store refuses with: the InputError's where() and what(), or where "" and what
// "built" when it builds.
struct Refusal {
  std::string where, what;
};
inline Refusal build_refusal(const std::vector<std::string>& images, const BuildOptions& o, const std::string& out) {
  try {
    build_store(images, o, out);
  } catch (const InputError& e) {
    return {e.where(), e.what()};
  }
  return {"", "built"};
}

}  // namespace vtsim::test
