// vtsim atlas build (docs/produced.md "vtsim atlas build"): brushes from files and patterns packed,
// each kept level written as an image with a manifest; bad brushes refused naming the file and
// the field, exit 2.
#include <doctest/doctest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/image_io.h"
#include "test_util.h"
#include "view_test_util.h"

namespace {

void atlas_cli_brush(const std::string& path, int s, std::uint8_t r) {
  std::vector<std::uint8_t> px;
  for (int y = 0; y < s; ++y)
    for (int x = 0; x < s; ++x) px.insert(px.end(), {r, static_cast<std::uint8_t>(x * 8), static_cast<std::uint8_t>(y * 8), 255});
  REQUIRE(vtsim::image_io::write_file(path, s, s, 4, vtsim::image_io::PixelType::u8, px.data(), true).status == vtsim::image_io::WriteStatus::ok);
}

}  // namespace

TEST_CASE("vtsim atlas build: brushes by pattern, one PNG per kept level and a manifest") {
  namespace fs = std::filesystem;
  const std::string dir = vtsim::test::temp_path("atlas_in"), out = vtsim::test::temp_path("atlas_out"), log = vtsim::test::temp_path("log.txt");
  fs::create_directories(dir);
  atlas_cli_brush(dir + "/b0.png", 16, 10);
  atlas_cli_brush(dir + "/b1.png", 16, 100);
  atlas_cli_brush(dir + "/b2.png", 16, 200);
  REQUIRE(vtsim::test::run_vtsim("atlas build '" + dir + "/b*.png' --cols 2 --border 4 -o " + out, log) == 0);
  CHECK(vtsim::test::contains(vtsim::test::slurp(log), "3 brushes of 16² in 2 x 2 cells, border 4, 3 levels kept"));
  const nlohmann::json man = nlohmann::json::parse(vtsim::test::slurp(out + "/atlas.json"));
  CHECK(man["format"] == "vtsim-atlas/1");
  CHECK(man["cols"] == 2);
  CHECK(man["side"] == 16);
  CHECK(man["levels_kept"] == 3);  // border 4, 2, 1
  CHECK(man["cells"][2]["file"] == dir + "/b2.png");
  CHECK(man["cells"][2]["x"] == 4);
  CHECK(man["cells"][2]["y"] == 24 + 4);
  CHECK(man["levels"][1]["width"] == 24);
  CHECK(man["levels"][2]["border"] == 1);
  auto in = vtsim::image_io::ImageReader::open_file(out + "/atlas_level0.png", true);
  REQUIRE(in.ok());
  REQUIRE(in.spec().width == 48);
  std::vector<std::uint8_t> px(48 * 48 * 4);
  REQUIRE(in.read(4, vtsim::image_io::PixelType::u8, px.data()) == vtsim::image_io::ReadStatus::ok);
  const auto at = [&](int x, int y) { return &px[(static_cast<std::size_t>(y) * 48 + static_cast<std::size_t>(x)) * 4]; };
  CHECK(at(4 + 3, 28 + 5)[0] == 200);  // brush 2's texel (3, 5)
  CHECK(at(4 + 3, 28 + 5)[1] == 24);
  CHECK(at(24 + 4 + 2, 4)[0] == 100);  // brush 1
  CHECK(at(3, 4 + 2)[1] == 15 * 8);    // the wrapped border: texel -1 is texel 15
  // --constant-border keeps the border at every level: all 5 levels (16² .. 1²), cells of 1 + 8.
  REQUIRE(vtsim::test::run_vtsim("atlas build " + dir + "/b0.png " + dir + "/b1.png --cols 2 --constant-border --transition 4 -q -o " + out, log) == 0);
  CHECK(vtsim::test::slurp(log).empty());
  const nlohmann::json man2 = nlohmann::json::parse(vtsim::test::slurp(out + "/atlas.json"));
  CHECK(man2["levels_kept"] == 5);
  CHECK(man2["transition"] == 4);
  CHECK(man2["levels"][4]["cell"] == 9);
  CHECK(fs::exists(out + "/atlas_level4.png"));
  fs::remove_all(dir);
  fs::remove_all(out);
  fs::remove(log);
}

TEST_CASE("vtsim atlas build: bad brushes exit 2 naming the file and the field") {
  namespace fs = std::filesystem;
  const std::string dir = vtsim::test::temp_path("atlas_bad"), out = vtsim::test::temp_path("atlas_bad_out"), log = vtsim::test::temp_path("log.txt");
  fs::create_directories(dir);
  atlas_cli_brush(dir + "/a.png", 16, 1);
  atlas_cli_brush(dir + "/npot.png", 12, 1);
  atlas_cli_brush(dir + "/big.png", 32, 1);
  const auto err = [&] { return vtsim::test::slurp(log); };
  CHECK(vtsim::test::run_vtsim("atlas build " + dir + "/npot.png -o " + out, log) == 2);
  CHECK(vtsim::test::contains(err(), dir + "/npot.png: brush side 12 is not a power of two"));
  CHECK(vtsim::test::run_vtsim("atlas build " + dir + "/a.png " + dir + "/big.png -o " + out, log) == 2);
  CHECK(vtsim::test::contains(err(), dir + "/big.png"));
  CHECK(vtsim::test::contains(err(), "all brushes must be the same size"));
  CHECK(vtsim::test::run_vtsim("atlas build " + dir + "/a.png " + dir + "/a.png --cols 1 --rows 1 -o " + out, log) == 2);
  CHECK(vtsim::test::contains(err(), "rows: 2 brushes do not fit 1 x 1 = 1 cells"));
  CHECK(vtsim::test::run_vtsim("atlas build " + dir + "/a.png " + dir + "/a.png --cols 2 --max-side 32 -o " + out, log) == 2);
  CHECK(vtsim::test::contains(err(), "over the"));
  CHECK(vtsim::test::run_vtsim("atlas build '" + dir + "/none*.png' -o " + out, log) == 2);
  CHECK(vtsim::test::contains(err(), dir + "/none*.png: no brush image matches this pattern"));
  CHECK(vtsim::test::run_vtsim("atlas build " + dir + "/missing.png -o " + out, log) == 2);
  CHECK(vtsim::test::contains(err(), "missing.png"));
  CHECK(vtsim::test::run_vtsim("atlas build " + dir + "/a.png --format jpg -o " + out, log) == 2);
  CHECK(vtsim::test::contains(err(), "--format"));
  fs::remove_all(dir);
  fs::remove_all(out);
  fs::remove(log);
}
