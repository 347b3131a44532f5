#include <doctest/doctest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <thread>

#include "core/error.h"
#include "store_test_util.h"
#include "stream/store/store_generator.h"
#include "stream/store/tile_store.h"

// Threaded code: also run by the TSan variant of scripts/test.sh (ctest -L threads).
TEST_SUITE_BEGIN("threads");

using namespace vtsim;
using store::CodecId;

namespace {

GenOptions small_options() {
  GenOptions o;
  o.width = 200;
  o.height = 130;
  o.tile = 32;
  o.border = 4;
  o.seed = 42;
  o.feature_texels = 128;
  o.layers = parse_gen_layers("albedo:zstd:3,normal:lz4,height:png", "--layers");
  return o;
}

// Level image assembled from the tile interiors [B, B+T) of every tile of one layer/level.
Image8 assemble_level(const TileStore& s, std::uint32_t layer, std::uint32_t l) {
  const auto& g = s.geometry();
  const std::uint32_t c = s.layer(layer).channels, S = g.stored_side();
  Image8 img;
  img.width = g.level_width(l);
  img.height = g.level_height(l);
  img.channels = c;
  img.texels.resize(std::size_t(img.width * img.height * c));
  AlignedBuffer scratch;
  std::vector<std::uint8_t> t(s.tile_bytes(layer));
  for (std::uint64_t ty = 0; ty < g.rows[l]; ++ty)
    for (std::uint64_t tx = 0; tx < g.cols[l]; ++tx) {
      s.read_tile(TileKey(layer, l, std::int64_t(tx), std::int64_t(ty)), scratch, t.data(), t.size());
      for (std::uint64_t j = 0; j < g.tile && ty * g.tile + j < img.height; ++j)
        for (std::uint64_t i = 0; i < g.tile && tx * g.tile + i < img.width; ++i)
          std::memcpy(&img.texels[std::size_t(((ty * g.tile + j) * img.width + tx * g.tile + i) * c)],
                      &t[std::size_t(((j + g.border) * S + i + g.border) * c)], c);
    }
  return img;
}

}  // namespace

TEST_CASE("the generator is deterministic: same seed and options give identical file bytes, any thread count") {
  test::TempDir dir;
  GenOptions o = small_options();
  o.threads = 1;
  generate_store(o, dir.file("a.vts"));
  o.threads = 3;
  generate_store(o, dir.file("b.vts"));
  const auto a = test::read_bytes(dir.file("a.vts"));
  CHECK(a.size() > 4096 * 10);
  CHECK(a == test::read_bytes(dir.file("b.vts")));
  o.seed = 43;
  generate_store(o, dir.file("c.vts"));
  CHECK(a != test::read_bytes(dir.file("c.vts")));
}

TEST_CASE("generated borders and padding equal the neighbours' texels (clamp-to-edge) at every level") {
  test::TempDir dir;
  const GenOptions o = small_options();
  generate_store(o, dir.file("g.vts"));
  const TileStore s = TileStore::open(dir.file("g.vts"));
  const auto& g = s.geometry();
  CHECK(s.layer(0).channels == 3);
  CHECK(s.layer(1).transfer == store::Transfer::linear);
  CHECK(s.layer(2).channels == 1);
  AlignedBuffer scratch;
  for (std::uint32_t layer = 0; layer < g.layers; ++layer)
    for (std::uint32_t l = 0; l < g.levels; ++l) {
      const Image8 level = assemble_level(s, layer, l);
      const std::uint32_t c = s.layer(layer).channels;
      const std::int64_t S = g.stored_side(), T = g.tile, B = g.border;
      std::vector<std::uint8_t> t(s.tile_bytes(layer));
      for (std::uint64_t ty = 0; ty < g.rows[l]; ++ty)
        for (std::uint64_t tx = 0; tx < g.cols[l]; ++tx) {
          s.read_tile(TileKey(layer, l, std::int64_t(tx), std::int64_t(ty)), scratch, t.data(), t.size());
          CHECK(t == generate_tile(o, layer, l, tx, ty));
          std::uint64_t bad = 0;
          for (std::int64_t j = 0; j < S; ++j)
            for (std::int64_t i = 0; i < S; ++i)
              bad += std::memcmp(&t[std::size_t((j * S + i) * c)],
                                 test::clamped(level, std::int64_t(tx) * T - B + i, std::int64_t(ty) * T - B + j), c) != 0;
          CAPTURE(layer);
          CAPTURE(l);
          CHECK(bad == 0);
        }
    }
}

TEST_CASE("generated levels are consistent: a coarse texel is close to the mean of its four children") {
  test::TempDir dir;
  GenOptions o;
  o.width = 512;
  o.height = 512;
  o.tile = 64;
  o.border = 0;
  o.seed = 7;
  o.feature_texels = 1024;  // octaves faded out at levels 1-3 have amplitude <= 32/1024
  o.layers = parse_gen_layers("height:raw", "--layers");
  generate_store(o, dir.file("h.vts"));
  const TileStore s = TileStore::open(dir.file("h.vts"));
  for (std::uint32_t l = 0; l < 3; ++l) {
    const Image8 fine = assemble_level(s, 0, l), coarse = assemble_level(s, 0, l + 1);
    double aligned = 0, shifted = 0;
    std::uint64_t n = 0;
    for (std::uint64_t y = 0; y + 1 < coarse.height; ++y)
      for (std::uint64_t x = 0; x + 1 < coarse.width; ++x, ++n) {
        auto box = [&](std::uint64_t fx, std::uint64_t fy) {
          return (double(*fine.at(fx, fy)) + double(*fine.at(fx + 1, fy)) + double(*fine.at(fx, fy + 1)) + double(*fine.at(fx + 1, fy + 1))) / 4;
        };
        aligned += std::abs(double(*coarse.at(x, y)) - box(2 * x, 2 * y));
        shifted += std::abs(double(*coarse.at(x, y)) - box(2 * x + 2, 2 * y + 2));  // the wrong children
      }
    aligned /= double(n);
    shifted /= double(n);
    CAPTURE(l);
    CAPTURE(aligned);
    CAPTURE(shifted);
    CHECK(aligned < 0.75);
    CHECK(shifted > 2 * aligned);
  }
}

TEST_CASE("generator options are checked") {
  CHECK_THROWS_AS(parse_gen_layers("roughness:zstd", "--layers"), InputError);
  CHECK_THROWS_AS(parse_gen_layers("albedo:zstd:99", "--layers"), InputError);
  try {
    parse_gen_layers("albedo:zstd,albedo:lz4", "--layers");
    FAIL("a repeated layer name");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()) == "--layers: layer name 'albedo' is used twice");
  }
  test::TempDir dir;
  GenOptions o = small_options();
  o.layers = parse_gen_layers("albedo:jpeg,normal:jpeg:80", "--layers");
  generate_store(o, dir.file("j.vts"));  // jpeg stores 3-channel layers
  o.width = 0;
  CHECK_THROWS_AS(generate_store(o, dir.file("x.vts")), InputError);
  o.width = 64;
  o.feature_texels = 1;
  CHECK_THROWS_AS(generate_store(o, dir.file("x.vts")), InputError);
  o.feature_texels = 1e308;
  try {
    generate_store(o, dir.file("x.vts"));
    FAIL("a feature size of 1e308");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).find("got 1e+308") != std::string::npos);
  }
  CHECK_FALSE(std::filesystem::exists(dir.file("x.vts")));
}

TEST_CASE("a generation interrupted by SIGINT exits 130 and leaves no output and no temporary file") {
  test::TempDir dir;
  const std::string out = dir.file("big.vts");
  const pid_t pid = ::fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    ::execl(VTSIM_CLI, VTSIM_CLI, "store", "gen", "-o", out.c_str(), "--size", "16384x16384", "--threads", "1",
            static_cast<char*>(nullptr));
    ::_exit(127);
  }
  // Wait until the writer's temporary file exists (the handler is installed before it), so the
  // signal lands mid-generation even on a slow sanitizer build.
  for (int i = 0; i < 600 && std::filesystem::is_empty(dir.path); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  CHECK_FALSE(std::filesystem::is_empty(dir.path));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ::kill(pid, SIGINT);
  int status = 0;
  REQUIRE(::waitpid(pid, &status, 0) == pid);
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 130);
  CHECK_FALSE(std::filesystem::exists(out));
  CHECK(std::filesystem::is_empty(dir.path));
}

TEST_SUITE_END();
