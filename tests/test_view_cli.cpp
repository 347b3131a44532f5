#include <doctest/doctest.h>

#include <cstdio>
#include <fstream>
#include <string>

#include "core/image_io.h"
#include "test_util.h"
#include "view_test_util.h"

using vtsim::test::slurp;

TEST_CASE("vtsim view writes the feedback image and prints counters") {
  const std::string png = vtsim::test::temp_path("view.png"), log = vtsim::test::temp_path("log.txt");
  REQUIRE(vtsim::test::run_vtsim("view --scene plane --pos 4096,4096,1.7 --pitch -10 --size 640x360 --divisor 4 --zoom 2 -o " + png, log) == 0);
  const std::string out = slurp(log);
  CHECK(out.find("buffer 160x90 (divisor 4)") != std::string::npos);
  CHECK(out.find("touched tiles (128 texels):") != std::string::npos);
  {
    auto in = vtsim::image_io::ImageReader::open_file(png, false);
    REQUIRE(in.ok());
    CHECK(in.spec().width == 320);
    CHECK(in.spec().height == 180);
    std::vector<unsigned char> px(320 * 180 * 3);
    REQUIRE(in.read(3, vtsim::image_io::PixelType::u8, px.data()) == vtsim::image_io::ReadStatus::ok);
    CHECK(px[0] + px[1] + px[2] == 0);                           // top-left: sky, black
    CHECK(px[(179 * 320) * 3] == 230);                           // bottom: level 0, red
  }
  std::remove(png.c_str());
  std::remove(log.c_str());
}

TEST_CASE("vtsim view: bad input exits 2 with the field or file named") {
  const std::string log = vtsim::test::temp_path("log.txt"), png = vtsim::test::temp_path("x.png");
  CHECK(vtsim::test::run_vtsim("view --pos 1,2 -o " + png, log) == 2);
  CHECK(slurp(log).find("--pos") != std::string::npos);
  CHECK(vtsim::test::run_vtsim("view --scene cube -o " + png, log) == 2);
  CHECK(vtsim::test::run_vtsim("view --divisor 0 -o " + png, log) == 2);
  CHECK(slurp(log).find("divisor") != std::string::npos);
  CHECK(vtsim::test::run_vtsim("view --size 10x0 -o " + png, log) == 2);
  const std::string obj = vtsim::test::temp_path("bad.obj");
  std::ofstream(obj) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n";
  CHECK(vtsim::test::run_vtsim("view --scene mesh --obj " + obj + " -o " + png, log) == 2);
  CHECK(slurp(log).find(obj + ":4: vertex index 7 is out of range") != std::string::npos);
  CHECK(vtsim::test::run_vtsim("view --scene heightfield --agl --pos -5000,0,2 -o " + png, log) == 2);
  CHECK(vtsim::test::run_vtsim("view -o /nonexistent/dir/x.png", log) == 2);
  // Heightfield options are checked even where the scene does not read them (generated noise
  // has no height scale).
  for (const char* opt : {"--height-scale nan", "--z0 inf", "--spacing 0"}) {
    CHECK(vtsim::test::run_vtsim(std::string("view --scene heightfield ") + opt + " -o " + png, log) == 2);
    CHECK(slurp(log).find(std::string(opt).substr(0, std::string(opt).find(' ')) + ": must be finite") != std::string::npos);
  }
  std::remove(obj.c_str());
  std::remove(log.c_str());
}
