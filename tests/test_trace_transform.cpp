// Transforms: axis conventions (a known pose through each), order of the steps, time, bad params.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <numbers>

#include "sim/trace/trace_transform.h"
#include "trace_test_util.h"

using namespace vtsim;
using vtsim::test::contains;
using vtsim::test::input_error;

namespace {

using vtsim::test::kForward;
using vtsim::test::kLeft;
using vtsim::test::kUp;

Trace one_pose(const glm::dvec3& p, const glm::dquat& q = glm::dquat(1, 0, 0, 0)) {
  Trace t;
  Pose pose;
  pose.pos_m = p;
  pose.q = q;
  t.poses.push_back(pose);
  return t;
}

using vtsim::test::check_vec;

// Where the FLU axes of the transformed pose point, for a source pose with identity orientation.
struct Frame {
  glm::dvec3 forward, left, up;
};
Frame frame_of(const std::string& world, const std::string& camera) {
  Trace t = one_pose({0, 0, 0});
  TraceTransform tf;
  tf.world_axes = world;
  tf.camera_axes = camera;
  transform_trace(t, tf);
  const glm::dquat q = t.poses[0].q;
  return {q * kForward, q * kLeft, q * kUp};
}

}  // namespace

TEST_CASE("axis conventions: names, letters and refusals") {
  CHECK(parse_world_axes("z-up", "w").spec == "ENU");
  CHECK(parse_world_axes("y-up", "w").spec == "EUS");
  CHECK(parse_world_axes("y-down", "w").spec == "EDN");
  CHECK(parse_world_axes("-y-up", "w").spec == "EDN");
  CHECK(parse_world_axes("ned", "w").spec == "NED");
  CHECK(parse_world_axes("wsu", "w").spec == "WSU");
  CHECK(parse_camera_axes("optical", "c").spec == "RDF");
  CHECK(parse_camera_axes("opengl", "c").spec == "RUB");
  CHECK(parse_camera_axes("flu", "c").spec == "FLU");
  CHECK(parse_camera_axes("imu-urf", "c").spec == "URF");
  CHECK(contains(input_error([] { parse_world_axes("ESU", "--up"); }), "left-handed"));
  CHECK(contains(input_error([] { parse_world_axes("EEU", "--up"); }), "same line"));
  CHECK(contains(input_error([] { parse_world_axes("x-up", "--up"); }), "--up: world axes 'x-up': unknown"));
  CHECK(contains(input_error([] { parse_camera_axes("RDX", "--camera"); }), "unknown"));
  CHECK(contains(input_error([] { parse_camera_axes("RDFU", "--camera"); }), "unknown"));
}

TEST_CASE("a camera at identity in each source convention") {
  SUBCASE("FLU in ENU: looks along +x, up is +z") {
    const Frame f = frame_of("z-up", "flu");
    check_vec(f.forward, {1, 0, 0});
    check_vec(f.up, {0, 0, 1});
  }
  SUBCASE("optical in ENU: looks up (optical z = world z), image up is world -y") {
    const Frame f = frame_of("z-up", "optical");
    check_vec(f.forward, {0, 0, 1});
    check_vec(f.up, {0, -1, 0});
    check_vec(f.left, {-1, 0, 0});
  }
  SUBCASE("OpenGL in ENU: looks down (-z), image up is world +y") {
    const Frame f = frame_of("z-up", "opengl");
    check_vec(f.forward, {0, 0, -1});
    check_vec(f.up, {0, 1, 0});
  }
  SUBCASE("OpenGL in a y-up world: looks north, level, upright") {
    const Frame f = frame_of("y-up", "opengl");
    check_vec(f.forward, {0, 1, 0});
    check_vec(f.up, {0, 0, 1});
    check_vec(f.left, {-1, 0, 0});
  }
  SUBCASE("optical in a y-down world (KITTI): looks north, level, upright") {
    const Frame f = frame_of("y-down", "optical");
    check_vec(f.forward, {0, 1, 0});
    check_vec(f.up, {0, 0, 1});
    check_vec(f.left, {-1, 0, 0});
  }
  SUBCASE("FLU in NED: forward is north, up is down") {
    const Frame f = frame_of("ned", "flu");
    check_vec(f.forward, {0, 1, 0});
    check_vec(f.up, {0, 0, -1});
  }
  SUBCASE("EuRoC IMU body in ENU: forward is body z (world up), up is body x (east)") {
    const Frame f = frame_of("z-up", "imu-urf");
    check_vec(f.forward, {0, 0, 1});
    check_vec(f.up, {1, 0, 0});
  }
}

TEST_CASE("world axes move positions - a rotated source orientation composes") {
  Trace t = one_pose({1, 2, 3});
  TraceTransform tf;
  tf.world_axes = "y-up";  // x east, y up, z south
  transform_trace(t, tf);
  CHECK(t.poses[0].pos_m == glm::dvec3(1, -3, 2));
  t = one_pose({1, 2, 3});
  tf.world_axes = "ned";
  transform_trace(t, tf);
  CHECK(t.poses[0].pos_m == glm::dvec3(2, 1, -3));
  // An optical camera in a z-up world rotated -90 degrees about world x: optical z (forward)
  // -> world +y, optical -y (image up) -> world +z: level, looking north.
  const double h = std::sqrt(0.5);
  t = one_pose({0, 0, 0}, glm::dquat(h, -h, 0, 0));
  tf = {};
  tf.camera_axes = "optical";
  transform_trace(t, tf);
  check_vec(t.poses[0].q * kForward, {0, 1, 0}, 1e-15);
  check_vec(t.poses[0].q * kUp, {0, 0, 1}, 1e-15);
}

TEST_CASE("position steps run recenter, axes, yaw, scale, offset in that order") {
  Trace t = one_pose({1, 0, 0});
  Pose p2 = t.poses[0];
  p2.t_s = 1.0;
  p2.pos_m = {2, 0, 0};
  t.poses.push_back(p2);
  TraceTransform tf;
  tf.recenter = true;
  tf.yaw_deg = 90.0;
  tf.scale = 10.0;
  tf.offset_m = {100, 200, 300};
  transform_trace(t, tf);
  check_vec(t.poses[0].pos_m, {100, 200, 300}, 0.0);
  check_vec(t.poses[1].pos_m, {100, 210, 300}, 1e-12);  // (1,0,0) yawed to (0,1,0), x10
  // Yaw also turns the view: identity looked east, now north.
  check_vec(t.poses[1].q * kForward, {0, 1, 0}, 1e-15);
  // Without recenter the absolute position is scaled.
  Trace u = one_pose({1, 2, 3});
  TraceTransform s;
  s.scale = 2.0;
  s.offset_m = {0.5, 0, 0};
  transform_trace(u, s);
  CHECK(u.poses[0].pos_m == glm::dvec3(2.5, 4, 6));
}

TEST_CASE("time steps: rebase, scale, offset") {
  Trace t = one_pose({0, 0, 0});
  t.poses[0].t_s = 10.0;
  Pose p = t.poses[0];
  p.t_s = 10.5;
  t.poses.push_back(p);
  Trace keep = t;
  TraceTransform tf;
  tf.time_scale = 2.0;
  tf.time_offset_s = 5.0;
  transform_trace(t, tf);
  CHECK(t.poses[0].t_s == 5.0);
  CHECK(t.poses[1].t_s == 6.0);
  tf.rebase_time = false;
  transform_trace(keep, tf);
  CHECK(keep.poses[0].t_s == 25.0);
  CHECK(keep.poses[1].t_s == 26.0);
}

TEST_CASE("the identity transform changes no bit") {
  Trace t = one_pose({1.0 / 3.0, -0.0, 1e-300}, glm::normalize(glm::dquat(0.1, 0.2, 0.3, 0.4)));
  const Trace before = t;
  transform_trace(t, TraceTransform{});
  CHECK(t.poses[0].pos_m == before.poses[0].pos_m);
  CHECK(t.poses[0].q == before.poses[0].q);
}

TEST_CASE("bad transform parameters name the field") {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  struct Case {
    const char* field;
    TraceTransform tf;
  };
  TraceTransform scale0, scale_neg, tscale0, off_nan, yaw_inf, vfov;
  scale0.scale = 0.0;
  scale_neg.scale = -2.0;
  tscale0.time_scale = 0.0;
  off_nan.offset_m.y = nan;
  yaw_inf.yaw_deg = std::numeric_limits<double>::infinity();
  vfov.vfov_deg = 200.0;
  const Case cases[] = {{"scale", scale0},       {"scale", scale_neg}, {"time_scale", tscale0},
                        {"offset", off_nan},      {"yaw", yaw_inf},     {"vfov", vfov}};
  for (const Case& c : cases) {
    Trace t = one_pose({0, 0, 0});
    const std::string e = input_error([&] { transform_trace(t, c.tf, "in.txt"); });
    CHECK(contains(e, std::string("in.txt: ") + c.field));
  }
  // A result out of range is refused too.
  Trace t = one_pose({1e9, 0, 0});
  TraceTransform big;
  big.scale = 1e3;
  CHECK(contains(input_error([&] { transform_trace(t, big, "in.txt"); }), "not within"));
}

TEST_CASE("yaw_pitch_quat") {
  check_vec(yaw_pitch_quat(0, 0) * kForward, {1, 0, 0}, 0.0);
  check_vec(yaw_pitch_quat(90, 0) * kForward, {0, 1, 0}, 1e-15);
  const double s = std::sin(std::numbers::pi / 6), c = std::cos(std::numbers::pi / 6);
  check_vec(yaw_pitch_quat(0, -30) * kForward, {c, 0, -s}, 1e-15);
  check_vec(yaw_pitch_quat(180, 30) * kForward, {-c, 0, s}, 1e-15);
  check_vec(yaw_pitch_quat(45, -30) * kUp, glm::dvec3(std::sqrt(0.5) * s, std::sqrt(0.5) * s, c), 1e-15);
}
