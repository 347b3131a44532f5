#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sys/wait.h>
#include <cstdio>

#include "core/error.h"
#include "core/image_io.h"
#include "store_test_util.h"
#include "test_util.h"
#include "stream/store/store_builder.h"
#include "stream/store/tile_store.h"

// Threaded code: also run by the TSan variant of scripts/test.sh (ctest -L threads).
TEST_SUITE_BEGIN("threads");

using namespace vtsim;
using store::CodecId;
using store::Transfer;

namespace {

// Every stored texel of every tile of `layer`, at every level, equals the clamp-addressed texel
// of the level image (true neighbours inside, clamp-to-edge outside). Returns tiles checked.
std::uint64_t check_tiles_against_levels(const TileStore& s, std::uint32_t layer, const std::vector<Image8>& levels) {
  const auto& g = s.geometry();
  const std::int64_t T = g.tile, B = g.border, S = g.stored_side();
  const std::uint32_t c = s.layer(layer).channels;
  AlignedBuffer scratch;
  std::vector<std::uint8_t> out(s.tile_bytes(layer));
  std::uint64_t tiles = 0;
  for (std::uint32_t l = 0; l < g.levels; ++l) {
    REQUIRE(levels[l].width == g.level_width(l));
    REQUIRE(levels[l].height == g.level_height(l));
    for (std::uint64_t ty = 0; ty < g.rows[l]; ++ty)
      for (std::uint64_t tx = 0; tx < g.cols[l]; ++tx) {
        const TileKey k(layer, l, std::int64_t(tx), std::int64_t(ty));
        s.read_tile(k, scratch, out.data(), out.size());
        std::uint64_t bad = 0;
        for (std::int64_t j = 0; j < S; ++j)
          for (std::int64_t i = 0; i < S; ++i) {
            const std::uint8_t* want = test::clamped(levels[l], std::int64_t(tx) * T - B + i, std::int64_t(ty) * T - B + j);
            bad += std::memcmp(&out[std::size_t((j * S + i) * c)], want, c) != 0;
          }
        CAPTURE(store::describe(k));
        CHECK(bad == 0);
        ++tiles;
      }
  }
  return tiles;
}

// Bilinear sample at continuous level coordinates (u, v) (texel k's centre at k + 0.5) from a
// fetch(x, y, ch) function.
template <class Fetch>
double bilinear(double u, double v, std::uint32_t ch, Fetch fetch) {
  const double x = u - 0.5, y = v - 0.5;
  const auto x0 = std::int64_t(std::floor(x)), y0 = std::int64_t(std::floor(y));
  const double fx = x - double(x0), fy = y - double(y0);
  return (1 - fx) * (1 - fy) * fetch(x0, y0, ch) + fx * (1 - fy) * fetch(x0 + 1, y0, ch) +
         (1 - fx) * fy * fetch(x0, y0 + 1, ch) + fx * fy * fetch(x0 + 1, y0 + 1, ch);
}

}  // namespace

TEST_CASE("mip filtering is the exact mean of each texel's level-0 footprint under ceil halving") {
  // 5 x 1, linear: level 1 texels cover [0,2) [2,4) [4,5); level 2 [0,4) [4,5); level 3 [0,5).
  Image8 img;
  img.width = 5;
  img.height = 1;
  img.channels = 1;
  img.texels = {0, 10, 20, 30, 250};
  const auto levels = build_mip_chain(img, Transfer::linear, 4);
  REQUIRE(levels.size() == 4);
  CHECK(levels[1].texels == std::vector<std::uint8_t>{5, 25, 250});
  CHECK(levels[2].texels == std::vector<std::uint8_t>{15, 250});
  CHECK(levels[3].texels == std::vector<std::uint8_t>{62});  // (0+10+20+30+250)/5, not (15+250)/2
  // 3 x 3 in both axes: the corner texel of level 1 covers one texel, an edge texel two.
  Image8 sq;
  sq.width = sq.height = 3;
  sq.channels = 1;
  sq.texels = {0, 20, 100, 40, 60, 200, 90, 30, 255};
  const auto l2 = build_mip_chain(sq, Transfer::linear, 3);
  CHECK(l2[1].texels == std::vector<std::uint8_t>{30, 150, 60, 255});
  CHECK(l2[2].texels == std::vector<std::uint8_t>{88});  // 795 / 9 = 88.3
}

TEST_CASE("sRGB layers are filtered in linear light, alpha and linear layers as stored") {
  Image8 img;
  img.width = 2;
  img.height = 1;
  img.channels = 4;
  img.texels = {0, 0, 255, 0, 255, 255, 255, 200};
  const auto s = build_mip_chain(img, Transfer::srgb, 2);
  // mean of 0 and 1 in linear light is 0.5 -> sRGB 0.7354 -> 188; alpha 100 is linear.
  CHECK(s[1].texels == std::vector<std::uint8_t>{188, 188, 255, 100});
  const auto l = build_mip_chain(img, Transfer::linear, 2);
  CHECK(l[1].texels == std::vector<std::uint8_t>{128, 128, 255, 100});
}

TEST_CASE("built tiles hold true neighbours in their borders at every level (1000 x 600, tile 128, border 4)") {
  test::TempDir dir;
  const Image8 rgb = test::make_image(1000, 600, 3, 1), grey = test::make_image(1000, 600, 1, 2);
  write_image8(dir.file("albedo.png"), rgb);
  write_image8(dir.file("mask.png"), grey);
  BuildOptions o;
  o.tile = 128;
  o.border = 4;
  o.codecs = {{CodecId::zstd, 3}, {CodecId::lz4, 0}};
  o.transfers = {Transfer::srgb, Transfer::linear};
  const std::string out = dir.file("t.vts");
  const BuildResult r = build_store({dir.file("albedo.png"), dir.file("mask.png")}, o, out);
  const TileStore s = TileStore::open(out);
  CHECK(r.tiles == s.geometry().tile_count());
  CHECK(s.level_count() == 11);  // 1000 -> 500 -> ... -> 1
  CHECK(s.layer(0).name == "albedo");
  CHECK(s.layer(1).name == "mask");
  CHECK(s.layer(1).channels == 1);
  const auto lv0 = build_mip_chain(rgb, Transfer::srgb, s.level_count());
  const auto lv1 = build_mip_chain(grey, Transfer::linear, s.level_count());
  CHECK(check_tiles_against_levels(s, 0, lv0) == s.geometry().tiles_per_layer);
  CHECK(check_tiles_against_levels(s, 1, lv1) == s.geometry().tiles_per_layer);
}

TEST_CASE("odd sizes, border 0 and a coarsest level other than 1x1 build correctly") {
  test::TempDir dir;
  for (auto [w, h, t, b, levels] : {std::tuple{37u, 23u, 8u, 2u, 0u}, std::tuple{37u, 23u, 8u, 0u, 3u}, std::tuple{1u, 1u, 4u, 4u, 0u},
                                    std::tuple{129u, 2u, 128u, 1u, 0u}}) {
    const unsigned width = w, border = b;  // clang 14 cannot capture a structured binding (CAPTURE's lambda)
    CAPTURE(width);
    CAPTURE(border);
    const Image8 img = test::make_image(w, h, 4, w + b);
    write_image8(dir.file("in.png"), img);
    BuildOptions o;
    o.tile = t;
    o.border = b;
    o.levels = levels;
    o.codecs = {{CodecId::png, 6}};
    o.threads = 2;
    build_store({dir.file("in.png")}, o, dir.file("o.vts"));
    const TileStore s = TileStore::open(dir.file("o.vts"));
    CHECK(s.level_count() == (levels ? levels : store::full_level_count(w, h)));
    check_tiles_against_levels(s, 0, build_mip_chain(img, Transfer::srgb, s.level_count()));
  }
}

TEST_CASE("bilinear sampling inside one tile, border included, matches the full level image: no bleeding (crazii 2017)") {
  test::TempDir dir;
  const Image8 img = test::make_image(300, 200, 3, 9);
  write_image8(dir.file("in.png"), img);
  BuildOptions o;
  o.tile = 32;
  o.border = 4;
  build_store({dir.file("in.png")}, o, dir.file("o.vts"));
  const TileStore s = TileStore::open(dir.file("o.vts"));
  const auto levels = build_mip_chain(img, Transfer::srgb, s.level_count());
  const auto& g = s.geometry();
  AlignedBuffer scratch;
  std::vector<std::uint8_t> tile(s.tile_bytes(0));
  std::uint64_t samples = 0;
  for (std::uint32_t l = 0; l < 3; ++l) {
    const Image8& lv = levels[l];
    // Sample points straddling every vertical and horizontal tile edge, up to half a texel past it.
    for (std::uint64_t e = 1; e < g.cols[l]; ++e)
      for (double d : {-0.5, -0.25, 0.0, 0.3, 0.5})
        for (double v : {0.5, 17.25, double(lv.height) - 0.7}) {
          const double u = double(e * g.tile) + d;
          // The tile that owns the sample point, sampled with its own stored texels only.
          const auto tx = std::uint64_t(std::floor(u)) / g.tile, ty = std::uint64_t(std::floor(v)) / g.tile;
          s.read_tile(TileKey(0, l, std::int64_t(tx), std::int64_t(ty)), scratch, tile.data(), tile.size());
          const std::int64_t ox = std::int64_t(tx * g.tile) - g.border, oy = std::int64_t(ty * g.tile) - g.border;
          const std::int64_t S = g.stored_side();
          for (std::uint32_t ch = 0; ch < 3; ++ch) {
            const double from_tile = bilinear(u, v, ch, [&](std::int64_t x, std::int64_t y, std::uint32_t c) {
              const std::int64_t i = x - ox, j = y - oy;
              REQUIRE(i >= 0);
              REQUIRE(j >= 0);
              REQUIRE(i < S);
              REQUIRE(j < S);
              return double(tile[std::size_t((j * S + i) * 3 + c)]);
            });
            const double from_level = bilinear(u, v, ch, [&](std::int64_t x, std::int64_t y, std::uint32_t c) {
              return double(test::clamped(lv, x, y)[c]);
            });
            CHECK(from_tile == from_level);
            ++samples;
          }
        }
  }
  CHECK(samples > 100);
}

TEST_CASE("an interrupted build leaves no output and no temporary file, an existing store survives") {
  test::TempDir dir;
  write_image8(dir.file("in.png"), test::make_image(300, 300, 3));
  BuildOptions o;
  o.tile = 32;
  const std::string out = dir.file("out.vts");
  struct Abort {};
  auto fail_halfway = [](double f) {
    if (f >= 0.5) throw Abort{};
  };
  CHECK_THROWS_AS(build_store({dir.file("in.png")}, o, out, fail_halfway), Abort);
  CHECK_FALSE(std::filesystem::exists(out));
  // Only the input is left in the directory.
  CHECK(std::distance(std::filesystem::directory_iterator(dir.path), std::filesystem::directory_iterator()) == 1);

  build_store({dir.file("in.png")}, o, out);
  const auto before = test::read_bytes(out);
  o.tile = 64;
  CHECK_THROWS_AS(build_store({dir.file("in.png")}, o, out, fail_halfway), Abort);
  CHECK(test::read_bytes(out) == before);
  CHECK(std::distance(std::filesystem::directory_iterator(dir.path), std::filesystem::directory_iterator()) == 2);
}

TEST_CASE("bad builder inputs are errors naming the file or option") {
  test::TempDir dir;
  write_image8(dir.file("a.png"), test::make_image(64, 64, 4));
  write_image8(dir.file("b.png"), test::make_image(64, 32, 3));
  const std::string out = dir.file("o.vts");
  auto where = [&](const std::vector<std::string>& imgs, const BuildOptions& o) {
    return test::build_refusal(imgs, o, out).where;
  };
  BuildOptions o;
  CHECK(where({dir.file("a.png"), dir.file("b.png")}, o) == dir.file("b.png"));  // sizes differ
  CHECK(where({dir.file("missing.png")}, o) == dir.file("missing.png"));
  o.codecs = {{CodecId::jpeg, 90}};
  CHECK(where({dir.file("a.png")}, o) == "--codec");  // jpeg has no alpha
  o.codecs = {};
  o.tile = 0;
  CHECK(where({dir.file("a.png")}, o) == "--tile");
  o.tile = 64;
  o.levels = 8;  // 64 x 64 has 7 levels
  CHECK(where({dir.file("a.png")}, o) == "--levels");
  o.levels = 0;
  o.layer_names = {"x", "y"};
  CHECK(where({dir.file("a.png")}, o) == "--layer-names");
  CHECK_FALSE(std::filesystem::exists(out));
}

TEST_CASE("a source image the reader reports damaged is refused unless accept_damaged (truncated JPEG, TIFF)") {
  // libjpeg and libtiff fill what a cut file lacks and OpenImageIO reports the read done with a
  // pending error: built as read, the store would hold grey (JPEG) or zero (TIFF) rows nobody drew.
  test::TempDir dir;
  for (const std::string name : {"cut.jpg", "cut.tif"}) {
    CAPTURE(name);
    const std::string path = dir.file(name);
    if (name == "cut.jpg") {
      write_image8(path, test::make_image(96, 200, 3));
    } else {  // 16-bit grey: libtiff decodes its strips one by one and reports the missing ones
      std::vector<std::uint16_t> px(64 * 64);
      for (std::size_t k = 0; k < px.size(); ++k) px[k] = static_cast<std::uint16_t>(k * 2654435761u >> 7);
      REQUIRE(image_io::write_file(path, 64, 64, 1, image_io::PixelType::u16, px.data(), false).status ==
              image_io::WriteStatus::ok);
    }
    test::cut_file(path, 0.6);
    BuildOptions o;
    const test::Refusal r = test::build_refusal({path}, o, dir.file("o.vts"));
    CHECK(r.where == path);
    CHECK(test::contains(r.what, "is damaged: "));
    CHECK(test::contains(r.what, "(the first 0 of"));  // one chunk of rows holds the whole image
    CHECK(test::contains(r.what, name == "cut.jpg" ? "Premature end of JPEG file" : "Read error"));
    CHECK_FALSE(std::filesystem::exists(dir.file("o.vts")));
    o.accept_damaged = true;
    CHECK(build_store({path}, o, dir.file("o.vts")).tiles > 0);
    std::filesystem::remove(dir.file("o.vts"));
  }
}

TEST_CASE("an image whose header claims more pixels than the memory limit is refused before it is read") {
  test::TempDir dir;
  // 52 bytes of PBM that OpenImageIO reads as 2^31 − 1 × 2 pixels: 4 GiB of 8-bit texels (fuzz
  // finding, tests/fuzz/corpus/image/oom_pbm_width_int_max.pnm).
  const std::string huge = dir.file("huge.pnm");
  std::ofstream(huge, std::ios::binary) << "P4444444444444444444444444444 2 3\n4 5 6 7\n8 0 10 15\n";
  BuildOptions o;
  o.memory_limit_bytes = std::uint64_t{64} << 20;
  {
    const test::Refusal r = test::build_refusal({huge}, o, dir.file("o.vts"));
    CHECK(r.where == huge);
    CHECK(test::contains(r.what, "more than the 64.0 MiB"));
  }
  // The limit counts every layer's level-0 texels, and the image being read also needs its chunk of
  // rows (here the whole 16 KiB image), OpenImageIO's strip buffer (image_io::read_scratch_bytes:
  // 64 MiB + 64 rows of 64 RGBA8 pixels) and, for a PNG, a whole copy of the image (an interlaced
  // PNG is read whole: whole_image_decode_bytes). Two 64 × 64 RGBA images (16 KiB each): the second
  // needs 16 + 16 KiB + 64 MiB + 16 + 16 KiB after the first's 16 KiB, so 64 MiB + 80 KiB fits and
  // 64 MiB + 72 KiB does not.
  write_image8(dir.file("a.png"), test::make_image(64, 64, 4));
  write_image8(dir.file("b.png"), test::make_image(64, 64, 4));
  o.memory_limit_bytes = (std::uint64_t{64} << 20) + (80 << 10);
  CHECK_NOTHROW(build_store({dir.file("a.png"), dir.file("b.png")}, o, dir.file("ab.vts")));
  o.memory_limit_bytes = (std::uint64_t{64} << 20) + (72 << 10);
  CHECK_THROWS_AS(build_store({dir.file("a.png"), dir.file("b.png")}, o, dir.file("ab2.vts")), InputError);
}

TEST_CASE("a JPEG 2000 source is charged OpenJPEG's whole-image decode: a limit the same TIFF fits refuses it") {
  // 64 × 64 RGB: the TIFF needs its 12 KiB of texels, a 12 KiB chunk and the 64 MiB + 12 KiB strip;
  // OpenJPEG also decodes the whole image to a 32-bit plane per channel: 48 KiB more (measured on
  // 4096² RGB: +197 MB of peak memory against the TIFF, docs/store-format.md §8).
  test::TempDir dir;
  const Image8 img = test::make_image(64, 64, 3);
  write_image8(dir.file("a.tif"), img);
  write_image8(dir.file("a.jp2"), img);
  BuildOptions o;
  o.memory_limit_bytes = (std::uint64_t{64} << 20) + (36 << 10);
  CHECK(build_store({dir.file("a.tif")}, o, dir.file("t.vts")).tiles > 0);
  const test::Refusal r = test::build_refusal({dir.file("a.jp2")}, o, dir.file("j.vts"));
  CHECK(r.where == dir.file("a.jp2"));
  CHECK(test::contains(r.what, "need 64.1 MiB to read, more than the 64.0 MiB"));
  o.memory_limit_bytes = (std::uint64_t{64} << 20) + (84 << 10);
  CHECK(build_store({dir.file("a.jp2")}, o, dir.file("j.vts")).tiles > 0);
}

TEST_CASE("a tiled image is read whole, and one whose header claims huge tiles is refused before it is read") {
  test::TempDir dir;
  // 40 × 24 pixels in 16 × 16 tiles: 3 × 2 tiles, the right and bottom ones partial.
  test::write_tiled_tiff(dir.file("tiled.tif"), 40, 24, 16, 16);
  const Image8 img = read_image8(dir.file("tiled.tif"), Transfer::linear);
  REQUIRE(img.width == 40);
  REQUIRE(img.height == 24);
  REQUIRE(img.channels == 1);
  std::uint64_t bad = 0;
  for (std::uint64_t y = 0; y < 24; ++y)
    for (std::uint64_t x = 0; x < 40; ++x) bad += *img.at(x, y) != std::uint8_t(x * 7 + y * 13);
  CHECK(bad == 0);
  // One tile holding the whole image.
  test::write_tiled_tiff(dir.file("one.tif"), 16, 16, 16, 16);
  const Image8 one = read_image8(dir.file("one.tif"), Transfer::linear);
  for (std::uint64_t y = 0; y < 16; ++y)
    for (std::uint64_t x = 0; x < 16; ++x) bad += *one.at(x, y) != std::uint8_t(x * 7 + y * 13);
  CHECK(bad == 0);
  // The same 64 × 64 pixels with a header claiming 65,520 × 65,520 tiles: OpenImageIO would
  // allocate a row of tiles, ~4 GiB a tile (read_scratch_bytes counts 5 such tiles: a row of one
  // and 4 more), before finding the data missing. Before the fix this took 24 GB and the OOM killer.
  const std::string lying = dir.file("lying.tif");
  test::write_tiled_tiff(lying, 64, 64, 64, 64, 65520, 65520);
  BuildOptions o;
  o.memory_limit_bytes = std::uint64_t{1} << 30;
  {
    const test::Refusal r = test::build_refusal({lying}, o, dir.file("o.vts"));
    CHECK(r.where == lying);
    CHECK(test::contains(r.what, "in 65520x65520 tiles need 20470.0 MiB to read, more than the 1024.0 MiB"));
  }
  CHECK_FALSE(std::filesystem::exists(dir.file("o.vts")));
}

TEST_CASE("the mip walk's peak is checked against the memory limit from the headers, before any image is read") {
  test::TempDir dir;
  // A PGM header of 12288 × 8192 pixels and no pixels: 96 MiB of level 0. Reading it needs 96 MiB,
  // a chunk of rows (1,365 rows: 4 KiB under 16 MiB), OpenImageIO's strip (64 MiB + 64 rows of
  // 12 KiB) and its PNM reader's copy of the whole image (96 MiB; image_io::whole_image_decode_bytes):
  // 272 MiB + 764 KiB. The walk holds level 0 and level 1 in float and 8 bits (6144 × 4096 × 5 B =
  // 120 MiB): 216 MiB, checked from the headers before any read.
  const std::string pgm = dir.file("big.pgm");
  std::ofstream(pgm, std::ios::binary) << "P5\n12288 8192\n255\n";
  BuildOptions o;
  o.memory_limit_bytes = (std::uint64_t{216} << 20) - 1;
  {
    const test::Refusal r = test::build_refusal({pgm}, o, dir.file("o.vts"));
    CHECK(r.where == pgm);
    CHECK(test::contains(r.what, "the mip walk over 1 layer(s) of 12288x8192 needs 216.0 MiB"));
  }
  // At exactly the peak the walk's check passes, and the read's own check refuses.
  o.memory_limit_bytes = std::uint64_t{216} << 20;
  {
    const test::Refusal r = test::build_refusal({pgm}, o, dir.file("o.vts"));
    CHECK(r.where == pgm);
    CHECK(test::contains(r.what, "need 272.7 MiB to read, more than the 216.0 MiB"));
  }
  // With room for the read, the build reads the image, which has no pixels: the first chunk of rows
  // fails (nothing was allocated for the rows after it).
  o.memory_limit_bytes = (std::uint64_t{272} << 20) + (764 << 10);
  {
    const test::Refusal r = test::build_refusal({pgm}, o, dir.file("o.vts"));
    CHECK(r.where == pgm);
    CHECK(test::contains(r.what, "cannot read the image: the reader gave no reason"));
  }
  // One level only: no walk, so only the read's need is checked.
  o.levels = 1;
  CHECK_THROWS_WITH_AS(build_store({pgm}, o, dir.file("o.vts")),
                       doctest::Contains("cannot read the image: the reader gave no reason"), InputError);
  o.memory_limit_bytes -= 1;
  CHECK_THROWS_WITH_AS(build_store({pgm}, o, dir.file("o.vts")), doctest::Contains("need 272.7 MiB to read"),
                       InputError);
  CHECK_FALSE(std::filesystem::exists(dir.file("o.vts")));
}

TEST_CASE("a default layer name is the image's stem cut at a character boundary, and an unusable stem names the image") {
  test::TempDir dir;
  // 30 bytes of 'a' and a 2-byte 'é': byte 31 would split the 'é', so the name stops before it.
  const std::string stem = std::string(30, 'a') + "\xC3\xA9";
  write_image8(dir.file(stem + ".png"), test::make_image(32, 32, 3));
  const std::string out = dir.file("o.vts");
  BuildOptions o;
  o.tile = 32;
  build_store({dir.file(stem + ".png")}, o, out);
  CHECK(TileStore::open(out).layer(0).name == std::string(30, 'a'));
  const std::string ctl = dir.file("a\x01" "b.png");
  write_image8(ctl, test::make_image(32, 32, 3));
  {
    const test::Refusal r = test::build_refusal({ctl}, o, out);
    CHECK(r.where == ctl);
    CHECK(test::contains(r.what, "name the layers with --layer-names"));
  }
}

TEST_CASE("the builder's output does not depend on the thread count") {
  test::TempDir dir;
  write_image8(dir.file("in.png"), test::make_image(200, 120, 3));
  BuildOptions o;
  o.tile = 16;
  o.threads = 1;
  build_store({dir.file("in.png")}, o, dir.file("a.vts"));
  o.threads = 3;
  build_store({dir.file("in.png")}, o, dir.file("b.vts"));
  CHECK(test::read_bytes(dir.file("a.vts")) == test::read_bytes(dir.file("b.vts")));
}

namespace {
// Runs the CLI; returns {exit code, stdout}. stderr goes to a file beside the outputs and is
// printed when the command dies of a signal or an unexpected failure (an ASan abort, 134, once
// failed this test with nothing to read).
std::pair<int, std::string> cli(const test::TempDir& dir, const std::string& args) {
  const test::CliRun r = test::run_vtsim_capture(args, dir.file("stderr.txt"));
  if (r.code != 0 && r.code != 2) MESSAGE("vtsim " << args << " exited " << r.code << "; stderr:\n" << r.err);
  return {r.code, r.out};
}
}  // namespace

TEST_CASE("vtsim store build / info --json / verify work end to end, bad options exit 2") {
  test::TempDir dir;
  write_image8(dir.file("a.png"), test::make_image(250, 130, 3));
  write_image8(dir.file("b.png"), test::make_image(250, 130, 2));
  const std::string out = dir.file("c.vts");
  auto [rc, text] = cli(dir, "store build " + dir.file("a.png") + " " + dir.file("b.png") + " -o " + out +
                        " --tile 64 --border 2 --codec zstd:5,png --layer-names col,ga --transfer srgb,linear");
  CHECK(rc == 0);
  CHECK(text.find("wrote " + out) != std::string::npos);
  auto [rc2, json] = cli(dir, "store info --json " + out);
  REQUIRE(rc2 == 0);
  const auto j = nlohmann::json::parse(json);
  CHECK(j["width"] == 250);
  CHECK(j["tile"] == 64);
  CHECK(j["border"] == 2);
  CHECK(j["levels"].size() == 9);
  CHECK(j["layers"][0]["name"] == "col");
  CHECK(j["layers"][0]["codec"] == "zstd");
  CHECK(j["layers"][0]["codec_param"] == 5);
  CHECK(j["layers"][1]["codec"] == "png");
  CHECK(j["layers"][1]["channels"] == 2);
  CHECK(j["layers"][1]["transfer"] == "linear");
  CHECK(j["compression_ratio"].get<double>() > 1.0);
  CHECK(cli(dir, "store verify " + out).first == 0);
  CHECK(cli(dir, "store extract " + out + " --layer 0 --level 1 -o " + dir.file("l1.png")).first == 0);
  const Image8 l1 = read_image8(dir.file("l1.png"), Transfer::linear);
  CHECK(l1.texels == build_mip_chain(test::make_image(250, 130, 3), Transfer::srgb, 2)[1].texels);
  CHECK(cli(dir, "store extract " + out + " --level 99 -o " + dir.file("x.png")).first == 2);
  CHECK(cli(dir, "store build " + dir.file("a.png") + " -o " + dir.file("x.vts") + " --codec webp").first == 2);
  CHECK(cli(dir, "store gen -o " + dir.file("x.vts") + " --size 12xq").first == 2);
  CHECK(cli(dir, "store gen -o " + dir.file("x.vts") + " --size 64x64 --layers rough:zstd").first == 2);
  CHECK(cli(dir, "store info " + dir.file("a.png")).first == 2);  // not a store: bad magic
  CHECK_FALSE(std::filesystem::exists(dir.file("x.vts")));
}

TEST_SUITE_END();
