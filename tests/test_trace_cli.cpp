// The `vtsim trace` commands through the real binary: happy paths, and bad input giving exit
// code 2 with the file and line on stderr.
#include <doctest/doctest.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "trace_test_util.h"

using vtsim::test::CliRun;
using vtsim::test::contains;
using vtsim::test::ScratchDir;
using vtsim::test::vtsim_run;
using vtsim::test::write_file;

namespace {

using vtsim::test::kData;
const std::string kOneRowTrace =
    "# vtsim-trace v1 image_width=1920 image_height=1080\nt_s,x_m,y_m,z_m,qw,qx,qy,qz,vfov_deg\n"
    "0,1,2,3,1,0,0,0,60\n";

}  // namespace

TEST_CASE("cli: help and usage errors") {
  ScratchDir dir;
  CliRun r = vtsim_run(dir, "trace --help");
  CHECK(r.code == 0);
  CHECK(contains(r.out, "import"));
  r = vtsim_run(dir, "trace gen --help");
  CHECK(r.code == 0);
  CHECK(contains(r.out, "walk_diagonal"));
  r = vtsim_run(dir, "trace gen fly -o " + dir.file("x.csv"));
  CHECK(r.code == 2);
  CHECK(contains(r.err, "unknown trace kind"));
  r = vtsim_run(dir, "trace gen walk");  // no -o
  CHECK(r.code == 2);
}

TEST_CASE("cli: gen, info --json, resample") {
  ScratchDir dir;
  const std::string walk = dir.file("walk.csv");
  CliRun r = vtsim_run(dir, "trace gen walk --pitch -10 --duration 5 --fps 30 -o " + walk);
  REQUIRE(r.code == 0);
  r = vtsim_run(dir, "trace info --json " + walk);
  REQUIRE(r.code == 0);
  const nlohmann::json j = nlohmann::json::parse(r.out);
  CHECK(j["frames"] == 151);
  CHECK(j["duration_s"] == 5.0);
  CHECK(j["format"] == "native");
  CHECK(j["path_length_m"].get<double>() == doctest::Approx(7.5));
  r = vtsim_run(dir, "trace resample --fps 10 " + walk + " -o " + dir.file("w10.csv"));
  REQUIRE(r.code == 0);
  r = vtsim_run(dir, "trace info " + dir.file("w10.csv"));
  CHECK(r.code == 0);
  CHECK(contains(r.out, "frames:        51"));
  // Orbit at a custom radius keeps one lap per duration.
  r = vtsim_run(dir, "trace gen orbit --radius 100 --start 100,200 -o - ");
  CHECK(r.code == 0);
  CHECK(contains(r.out, "radius_m=100"));
}

TEST_CASE("cli: import with transform and resample - KITTI with a rate - y-down spelled -y-up") {
  ScratchDir dir;
  const std::string out = dir.file("fr1.csv");
  CliRun r = vtsim_run(dir, "trace import --format tum --scale 100 --recenter --offset 4096,4096,300 --resample 60 " +
                             kData + "/tum_fr1_xyz_excerpt.txt -o " + out);
  REQUIRE(r.code == 0);
  CHECK(contains(r.err, "read 200 poses (tum, 203 lines)"));
  r = vtsim_run(dir, "trace info --json " + out);
  REQUIRE(r.code == 0);
  const nlohmann::json j = nlohmann::json::parse(r.out);
  CHECK(j["frames"] == 120);  // 1.99 s at 60 Hz: frames 0 .. 119
  CHECK(j["bbox_max_m"][2].get<double>() >= 300.0);
  r = vtsim_run(dir, "trace import --format kitti --rate 10 --up=-y-up " + kData + "/kitti_synthetic_poses.txt -o " +
                         dir.file("k.csv"));
  CHECK(r.code == 0);
  r = vtsim_run(dir, "trace info --rate 10 " + kData + "/kitti_synthetic_poses.txt");
  CHECK(r.code == 0);
  CHECK(contains(r.out, "frames:        20"));
  r = vtsim_run(dir, "trace import --format kitti " + kData + "/kitti_synthetic_poses.txt -o " + dir.file("k.csv"));
  CHECK(r.code == 2);
  CHECK(contains(r.err, "times file or a rate"));
  r = vtsim_run(dir, "trace import --scale 0 " + kData + "/tum_fr1_xyz_excerpt.txt -o " + dir.file("z.csv"));
  CHECK(r.code == 2);
  CHECK(contains(r.err, "scale"));
  r = vtsim_run(dir, "trace import --up sideways " + kData + "/tum_fr1_xyz_excerpt.txt -o " + dir.file("z.csv"));
  CHECK(r.code == 2);
  CHECK(contains(r.err, "world axes 'sideways'"));
  r = vtsim_run(dir, "trace info --strict " + kData + "/tum_fr2_desk_excerpt.txt");
  CHECK(r.code == 2);
  CHECK(contains(r.err, "tum_fr2_desk_excerpt.txt:103:"));
  r = vtsim_run(dir, "trace info " + kData + "/tum_fr2_desk_excerpt.txt");
  CHECK(r.code == 0);
  CHECK(contains(r.out, "1 poses with a repeated time dropped"));
}

TEST_CASE("cli: bad input gives exit code 2 and names the file and line") {
  ScratchDir dir;
  struct Case {
    const char* label;
    const char* command;  // "info" or "import --format tum"
    std::string text;
    int line;
  };
  const std::string tum_ok = "1.0 0 0 0 0 0 0 1\n";
  const Case cases[] = {
      {"NaN", "info", kOneRowTrace + "0.5,nan,2,3,1,0,0,0,60\n", 4},
      {"inf", "info", kOneRowTrace + "0.5,1,-inf,3,1,0,0,0,60\n", 4},
      {"time backwards", "info", kOneRowTrace + "-0.5,1,2,3,1,0,0,0,60\n", 4},
      {"duplicate time (strict)", "info --strict", kOneRowTrace + "0,1,2,3,1,0,0,0,60\n", 4},
      {"quaternion far from unit", "info", kOneRowTrace + "0.5,1,2,3,0.5,0,0,0,60\n", 4},
      {"zero quaternion", "info", kOneRowTrace + "0.5,1,2,3,0,0,0,0,60\n", 4},
      {"missing column", "info", kOneRowTrace + "0.5,1,2,3,1,0,0,0\n", 4},
      {"extra column", "info", kOneRowTrace + "0.5,1,2,3,1,0,0,0,60,1\n", 4},
      {"empty file", "info --format native", "", 1},
      {"binary garbage", "info --format native", std::string("\x1f\x8b\x08\x00\x00\x00", 6), 1},
      {"non-UTF-8", "info", kOneRowTrace + "# \xff\n", 4},
      {"huge line", "info", kOneRowTrace + std::string(100000, '7') + "\n", 4},
      {"tum NaN", "import --format tum", tum_ok + "1.1 0 nan 0 0 0 0 1\n", 2},
      {"tum backwards", "import --format tum", tum_ok + "0.9 0 0 0 0 0 0 1\n", 2},
      {"tum missing column", "import --format tum", tum_ok + "1.1 0 0 0 0 0 1\n", 2},
      {"tum quaternion", "import --format tum", tum_ok + "1.1 0 0 0 0 0 0 3\n", 2},
      {"tum garbage", "import --format tum", tum_ok + std::string("\x00\x01\x02", 3) + "\n", 2},
      {"euroc short", "import --format euroc", "#timestamp\n1,0,0,0,1,0,0\n", 2},
      {"kitti not a rotation", "import --format kitti --rate 10", "1 0 0 0 0 1 0 0 0 0 1 0\n1 1 0 0 0 1 0 0 0 0 1 0\n", 2},
      {"undetectable", "info", "1 2 3\n", 1},
  };
  for (const Case& c : cases) {
    CAPTURE(c.label);
    const std::string path = dir.file("bad.txt");
    write_file(path, c.text);
    std::string args = std::string("trace ") + c.command + " " + path;
    if (contains(c.command, "import")) args += " -o " + dir.file("out.csv");
    const CliRun r = vtsim_run(dir, args);
    CAPTURE(r.err);
    CHECK(r.code == 2);
    CHECK(contains(r.err, path + ":" + std::to_string(c.line) + ":"));
  }
  const CliRun r = vtsim_run(dir, "trace info " + dir.file("does_not_exist.csv"));
  CHECK(r.code == 2);
  CHECK(contains(r.err, "does_not_exist.csv: cannot open"));
}
