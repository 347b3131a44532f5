// Importers (TUM RGB-D, EuRoC, KITTI) on excerpts of real recordings and synthetic files.
#include <doctest/doctest.h>

#include <cmath>
#include <numbers>
#include <string>

#include "sim/trace/trace_import.h"
#include "sim/trace/trace_io.h"
#include "trace_test_util.h"

using namespace vtsim;
using vtsim::test::contains;
using vtsim::test::input_error;
using vtsim::test::ScratchDir;
using vtsim::test::write_file;

namespace {

using vtsim::test::check_vec;
using vtsim::test::kData;
const std::string kTumFr1 = kData + "/tum_fr1_xyz_excerpt.txt";
const std::string kTumFr2 = kData + "/tum_fr2_desk_excerpt.txt";
const std::string kEuroc = kData + "/euroc_V1_02_excerpt.csv";
const std::string kKitti = kData + "/kitti_synthetic_poses.txt";
const std::string kKittiTimes = kData + "/kitti_synthetic_times.txt";

using vtsim::test::kForward;
using vtsim::test::kLeft;
using vtsim::test::kUp;

}  // namespace

TEST_CASE("TUM import: times exact from 0, positions as recorded, optical camera -> FLU") {
  ImportOptions o;
  o.format = "tum";
  TraceLoadReport rep;
  const Trace t = import_trace(kTumFr1, o, &rep);
  CHECK(rep.format == "tum");
  CHECK(rep.lines == 203);
  REQUIRE(t.poses.size() == 200);
  CHECK(rep.repairs.total() == 0);  // 4-decimal quaternions are unit to their printed precision
  CHECK(t.poses[0].t_s == 0.0);
  CHECK(t.poses[1].t_s == 0.0099);  // 1305031098.6758 - 1305031098.6659, exact in nanoseconds
  CHECK(t.poses[199].t_s == 1.99);  // line 203: 1305031100.6559
  CHECK(t.poses[0].pos_m == glm::dvec3(1.3563, 0.6305, 1.6380));
  CHECK(t.image_width == 1920);
  CHECK(t.poses[0].vfov_deg == 60.0);
  // First line: qx qy qz qw = 0.6132 0.5962 -0.3311 -0.3986; the optical frame's z (forward),
  // -y (up) and -x (left) are the FLU camera's x, z and y.
  const glm::dquat src = glm::normalize(glm::dquat(-0.3986, 0.6132, 0.5962, -0.3311));
  const glm::dquat& q = t.poses[0].q;
  check_vec(q * kForward, src * glm::dvec3(0, 0, 1), 1e-12);
  check_vec(q * kUp, src * glm::dvec3(0, -1, 0), 1e-12);
  check_vec(q * kLeft, src * glm::dvec3(-1, 0, 0), 1e-12);
  // The Kinect looks slightly down and the image is upright: forward z < 0, up z > 0.
  CHECK((q * kForward).z < 0.0);
  CHECK((q * kUp).z > 0.8);
}

TEST_CASE("TUM import: the repeated time stamp in fr2_desk is dropped and counted") {
  ImportOptions o;
  TraceLoadReport rep;
  const Trace t = import_trace(kTumFr2, o, &rep);  // format detected
  CHECK(rep.format == "tum");
  CHECK(rep.repairs.duplicate_times_dropped == 1);
  CHECK(t.poses.size() == 199);
  // The first of the two poses at 1311868229.5760 (excerpt line 102) is kept.
  bool found = false;
  for (const Pose& p : t.poses)
    if (p.pos_m == glm::dvec3(1.4054, 0.9615, 1.3677)) found = true;
  CHECK(found);
  o.read.strict = true;
  const std::string e = input_error([&] { import_trace(kTumFr2, o); });
  CHECK(contains(e, kTumFr2 + ":103:"));
  CHECK(contains(e, "line 102"));
}

TEST_CASE("EuRoC import: nanosecond times, w-first quaternions, IMU body frame, extra columns ignored") {
  ImportOptions o;
  TraceLoadReport rep;
  const Trace t = import_trace(kEuroc, o, &rep);
  CHECK(rep.format == "euroc");
  REQUIRE(t.poses.size() == 200);
  CHECK(t.poses[1].t_s == 4999936 / 1e9);  // 1403715524912143104 - 1403715524907143168 ns
  CHECK(t.poses[0].pos_m == glm::dvec3(0.515356, 1.996773, 0.971104));
  // q_RS = (w 0.161996, x 0.789985, y -0.205376, z 0.554528); body x up, y right, z forward.
  const glm::dquat src = glm::normalize(glm::dquat(0.161996, 0.789985, -0.205376, 0.554528));
  const glm::dquat& q = t.poses[0].q;
  check_vec(q * kForward, src * glm::dvec3(0, 0, 1), 1e-12);
  check_vec(q * kUp, src * glm::dvec3(1, 0, 0), 1e-12);
  check_vec(q * kLeft, src * glm::dvec3(0, -1, 0), 1e-12);
  CHECK((q * kUp).z > 0.9);  // the MAV hovers level: the body x axis is nearly world up
  // With the optical convention instead, forward is the same axis and the image is rolled.
  o.transform.camera_axes = "optical";
  const Trace t2 = import_trace(kEuroc, o);
  check_vec(t2.poses[0].q * kForward, src * glm::dvec3(0, 0, 1), 1e-12);
  check_vec(t2.poses[0].q * kUp, src * glm::dvec3(0, -1, 0), 1e-12);
}

TEST_CASE("KITTI import: rotation matrices, times file or fixed rate, y-down world") {
  ImportOptions o;
  o.format = "kitti";
  o.kitti_times_path = kKittiTimes;
  TraceLoadReport rep;
  const Trace t = import_trace(kKitti, o, &rep);
  CHECK(rep.format == "kitti");
  CHECK(rep.repairs.total() == 0);
  REQUIRE(t.poses.size() == 20);
  for (int i = 0; i < 20; ++i) {
    CAPTURE(i);
    const Pose& p = t.poses[static_cast<std::size_t>(i)];
    CHECK(p.t_s == static_cast<double>(i * 100000000LL) / 1e9);
    // KITTI (0, 0, i) in the first camera's frame (x right, y down, z forward) is i m north.
    CHECK(p.pos_m == glm::dvec3(0.0, i, 0.0));
    // Yawing by 5i degrees about the camera's down axis turns the view from north towards east.
    const double a = 5.0 * i * std::numbers::pi / 180.0;
    check_vec(p.q * kForward, {std::sin(a), std::cos(a), 0.0}, 2e-6);
    check_vec(p.q * kUp, {0.0, 0.0, 1.0}, 2e-6);
  }
  o.kitti_times_path.clear();
  o.kitti_rate_hz = 10.0;
  const Trace r = import_trace(kKitti, o);
  CHECK(r.poses[3].t_s == 0.3);
  CHECK(r.poses[19].t_s == 1.9);
}

TEST_CASE("KITTI import errors name the file and line") {
  ScratchDir dir;
  ImportOptions o;
  o.format = "kitti";
  CHECK(contains(input_error([&] { import_trace(kKitti, o); }), "times file or a rate"));
  o.kitti_rate_hz = 10.0;
  o.kitti_times_path = kKittiTimes;
  CHECK(contains(input_error([&] { import_trace(kKitti, o); }), "exactly one"));
  o.kitti_rate_hz = 0.0;

  write_file(dir.file("short_times.txt"), "0\n0.1\n");
  o.kitti_times_path = dir.file("short_times.txt");
  CHECK(contains(input_error([&] { import_trace(kKitti, o); }), dir.file("short_times.txt") + ":2: 2 times for 20 poses"));
  std::string many;
  for (int i = 0; i < 21; ++i) many += std::to_string(i) + "\n";
  write_file(dir.file("long_times.txt"), many);
  o.kitti_times_path = dir.file("long_times.txt");
  CHECK(contains(input_error([&] { import_trace(kKitti, o); }), dir.file("long_times.txt") + ":21: more times than poses"));
  write_file(dir.file("back_times.txt"), "0\n1\n0.5\n");
  o.kitti_times_path = dir.file("back_times.txt");
  CHECK(contains(input_error([&] { import_trace(kKitti, o); }), dir.file("back_times.txt") + ":3:"));

  o.kitti_times_path.clear();
  o.kitti_rate_hz = 10.0;
  const std::string id = "1 0 0 0 0 1 0 0 0 0 1 0\n";
  write_file(dir.file("scaled.txt"), id + "2 0 0 0 0 2 0 0 0 0 2 0\n");
  CHECK(contains(input_error([&] { import_trace(dir.file("scaled.txt"), o); }), dir.file("scaled.txt") + ":2: the 3x3 block is not a rotation"));
  write_file(dir.file("mirror.txt"), id + "-1 0 0 0 0 1 0 0 0 0 1 0\n");
  CHECK(contains(input_error([&] { import_trace(dir.file("mirror.txt"), o); }), dir.file("mirror.txt") + ":2: the 3x3 block is not a rotation"));
  write_file(dir.file("eleven.txt"), id + "1 0 0 0 0 1 0 0 0 0 1\n");
  CHECK(contains(input_error([&] { import_trace(dir.file("eleven.txt"), o); }), dir.file("eleven.txt") + ":2: expected 12 fields"));
  // A slightly skewed matrix is repaired and counted; strict refuses it.
  write_file(dir.file("skew.txt"), id + "1 0.0005 0 0 0 1 0 0 0 0 1 0\n");
  TraceLoadReport rep;
  CHECK(import_trace(dir.file("skew.txt"), o, &rep).poses.size() == 2);
  CHECK(rep.repairs.rotations_orthonormalised == 1);
  o.read.strict = true;
  CHECK(contains(input_error([&] { import_trace(dir.file("skew.txt"), o); }), dir.file("skew.txt") + ":2:"));
}

TEST_CASE("TUM and EuRoC bad input names the file and line") {
  ScratchDir dir;
  const std::string tum_ok = "1.0 0 0 0 0 0 0 1\n";
  struct Case {
    const char* label;
    const char* format;
    std::string text;
    int line;
    const char* what;
  };
  const Case cases[] = {
      {"tum 7 fields", "tum", tum_ok + "1.1 0 0 0 0 0 0\n", 2, "expected 8 fields"},
      {"tum 9 fields", "tum", tum_ok + "1.1 0 0 0 0 0 0 1 5\n", 2, "expected 8 fields"},
      {"tum NaN", "tum", tum_ok + "1.1 nan 0 0 0 0 0 1\n", 2, "not finite"},
      {"tum NaN time", "tum", tum_ok + "nan 0 0 0 0 0 0 1\n", 2, "not a number"},
      {"tum inf time", "tum", tum_ok + "inf 0 0 0 0 0 0 1\n", 2, "not a number"},
      {"tum huge time", "tum", tum_ok + "1e30 0 0 0 0 0 0 1\n", 2, "out of range"},
      {"tum backwards", "tum", tum_ok + "0.5 0 0 0 0 0 0 1\n", 2, "time goes backwards"},
      {"tum quaternion", "tum", tum_ok + "1.1 0 0 0 0 0 0 0.5\n", 2, "quaternion norm"},
      {"tum zero quaternion", "tum", tum_ok + "1.1 0 0 0 0 0 0 0\n", 2, "zero quaternion"},
      {"tum binary", "tum", tum_ok + std::string("PK\x03\x04\0\0", 6), 2, "NUL byte"},
      {"tum png header", "tum", tum_ok + "\x89PNG\r\n\x1a\n", 2, "invalid UTF-8"},
      {"tum latin-1", "tum", "# caf\xe9\n" + tum_ok, 1, "invalid UTF-8"},
      {"tum empty", "tum", "", 1, "empty file"},
      {"tum comments only", "tum", "# a\n# b\n\n", 3, "no poses"},
      {"euroc 7 fields", "euroc", "1,0,0,0,1,0,0\n", 1, "at least 8 fields"},
      {"euroc float time", "euroc", "1.5e9,0,0,0,1,0,0,0\n2.5e9,0,0,0,1,0,0,0\n3.5.1,0,0,0,1,0,0,0\n", 3,
       "not a number"},
      {"euroc negative w far", "euroc", "1,0,0,0,-2,0,0,0\n", 1, "quaternion norm"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.label);
    const std::string path = dir.file("bad.txt");
    write_file(path, c.text);
    ImportOptions o;
    o.format = c.format;
    const std::string e = input_error([&] { import_trace(path, o); });
    CAPTURE(e);
    CHECK(contains(e, path + ":" + std::to_string(c.line) + ":"));
    CHECK(contains(e, c.what));
  }
}

TEST_CASE("TUM: CRLF, tabs and trailing blank lines are accepted") {
  ScratchDir dir;
  write_file(dir.file("crlf.txt"),
             "# timestamp tx ty tz qx qy qz qw\r\n10.5\t1 2 3  0 0 0 1\r\n11.0 1 2 4 0 0 0 1\r\n\r\n\r\n");
  const Trace t = import_trace(dir.file("crlf.txt"));
  REQUIRE(t.poses.size() == 2);
  CHECK(t.poses[1].t_s == 0.5);
  CHECK(t.poses[1].pos_m.z == 4.0);
}

TEST_CASE("format detection") {
  ScratchDir dir;
  CHECK(detect_trace_format(kTumFr1) == "tum");
  CHECK(detect_trace_format(kEuroc) == "euroc");
  CHECK(detect_trace_format(kKitti) == "kitti");
  write_file(dir.file("n.csv"), "# vtsim-trace v1 image_width=2 image_height=2\nt_s,x_m,y_m,z_m,qw,qx,qy,qz,vfov_deg\n0,0,0,0,1,0,0,0,60\n");
  CHECK(detect_trace_format(dir.file("n.csv")) == "native");
  write_file(dir.file("headerless_euroc.csv"), "1,0,0,0,1,0,0,0,5,5\n");
  CHECK(detect_trace_format(dir.file("headerless_euroc.csv")) == "euroc");
  write_file(dir.file("odd.txt"), "# five numbers\n1 2 3 4 5\n");
  const std::string e = input_error([&] { detect_trace_format(dir.file("odd.txt")); });
  CHECK(contains(e, dir.file("odd.txt") + ":2: cannot tell the trace format"));
  write_file(dir.file("empty.txt"), "");
  CHECK(contains(input_error([&] { detect_trace_format(dir.file("empty.txt")); }), ":1: empty file"));
  CHECK(contains(input_error([&] { parse_trace_format("csv", "--format"); }), "--format"));
  // load_any_trace: native as stored (no rebase), other formats imported with defaults.
  write_file(dir.file("late.csv"), "# vtsim-trace v1 image_width=2 image_height=2\nt_s,x_m,y_m,z_m,qw,qx,qy,qz,vfov_deg\n5,0,0,0,1,0,0,0,60\n");
  CHECK(load_any_trace(dir.file("late.csv")).poses[0].t_s == 5.0);
  CHECK(load_any_trace(kTumFr1).poses.size() == 200);
}

TEST_CASE("import applies the transform after the format's conventions - keep-time keeps digits") {
  ImportOptions o;
  o.transform.scale = 100.0;
  o.transform.recenter = true;
  o.transform.offset_m = {4096.0, 4096.0, 300.0};
  o.transform.time_scale = 2.0;
  o.transform.vfov_deg = 75.0;
  o.image_width = 640;
  o.image_height = 360;
  const Trace t = import_trace(kTumFr1, o);
  CHECK(t.poses[0].pos_m == glm::dvec3(4096.0, 4096.0, 300.0));
  CHECK(std::abs(t.poses[1].pos_m.x - (4096.0 + 100.0 * (1.3543 - 1.3563))) < 1e-9);
  CHECK(t.poses[1].t_s == 0.0198);
  CHECK(t.poses[5].vfov_deg == 75.0);
  CHECK(t.image_width == 640);
  ImportOptions keep;
  keep.transform.rebase_time = false;
  const Trace k = import_trace(kTumFr1, keep);
  CHECK(k.poses[0].t_s == 1305031098.6659);
  CHECK(k.poses[1].t_s - k.poses[0].t_s == doctest::Approx(0.0099).epsilon(1e-6));
  ImportOptions bad;
  bad.image_width = 10;  // height missing
  CHECK(contains(input_error([&] { import_trace(kTumFr1, bad); }), "image"));
}
