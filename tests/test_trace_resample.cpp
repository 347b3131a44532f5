// Resampling: linear positions, shortest-arc slerp, irregular and gappy input, frame times.
#include <doctest/doctest.h>

#include <cmath>
#include <numbers>

#include "sim/trace/trace_resample.h"
#include "sim/trace/trace_stats.h"
#include "trace_test_util.h"

using namespace vtsim;
using vtsim::test::contains;
using vtsim::test::input_error;

namespace {

Pose pose_at(double t, glm::dvec3 p, glm::dquat q = glm::dquat(1, 0, 0, 0), double vfov = 60.0) {
  Pose x;
  x.t_s = t;
  x.pos_m = p;
  x.q = q;
  x.vfov_deg = vfov;
  return x;
}

glm::dquat about_z(double deg) {
  const double h = deg * std::numbers::pi / 360.0;
  return {std::cos(h), 0.0, 0.0, std::sin(h)};
}

}  // namespace

TEST_CASE("resample: linear position and vfov against hand values") {
  Trace in;
  in.poses = {pose_at(0.0, {0, 0, 0}, glm::dquat(1, 0, 0, 0), 40.0), pose_at(1.0, {10, -4, 2}, glm::dquat(1, 0, 0, 0), 80.0)};
  const Trace out = resample(in, 4.0);
  REQUIRE(out.poses.size() == 5);
  const double xs[] = {0, 2.5, 5, 7.5, 10}, ys[] = {0, -1, -2, -3, -4}, zs[] = {0, 0.5, 1, 1.5, 2};
  for (int k = 0; k < 5; ++k) {
    const Pose& p = out.poses[static_cast<std::size_t>(k)];
    CHECK(p.t_s == k / 4.0);
    CHECK(p.pos_m.x == xs[k]);
    CHECK(p.pos_m.y == ys[k]);
    CHECK(p.pos_m.z == zs[k]);
    CHECK(p.vfov_deg == 40.0 + 10.0 * k);
  }
}

TEST_CASE("slerp: constant angular rate along the shortest arc") {
  const glm::dquat a = about_z(0), b = about_z(90);
  const glm::dquat m = slerp_shortest(a, b, 0.5);
  CHECK(m.w == doctest::Approx(std::cos(std::numbers::pi / 8)).epsilon(1e-15));
  CHECK(m.z == doctest::Approx(std::sin(std::numbers::pi / 8)).epsilon(1e-15));
  CHECK(std::abs(rotation_angle(a, slerp_shortest(a, b, 0.25)) - std::numbers::pi / 8) < 1e-15);
  // -b is the same rotation as b: the result is still the 45-degree rotation, not a 135-degree one.
  const glm::dquat n = slerp_shortest(a, -b, 0.5);
  CHECK(std::abs(rotation_angle(n, m)) < 1e-15);
  // 350 degrees about z is -10 degrees: halfway is -5 degrees.
  CHECK(std::abs(rotation_angle(slerp_shortest(a, about_z(350), 0.5), about_z(-5))) < 1e-14);
  // Tiny and exactly-equal rotations are stable.
  const glm::dquat tiny = about_z(1e-9);
  CHECK(std::abs(rotation_angle(slerp_shortest(a, tiny, 0.5), about_z(0.5e-9))) < 1e-20);
  CHECK(slerp_shortest(b, b, 0.3) == b);
}

TEST_CASE("resample: orientation by slerp at the frame times") {
  Trace in;
  in.poses = {pose_at(0.0, {0, 0, 0}, about_z(0)), pose_at(2.0, {0, 0, 0}, about_z(120))};
  const Trace out = resample(in, 2.0);
  REQUIRE(out.poses.size() == 5);
  for (int k = 0; k < 5; ++k)
    CHECK(std::abs(rotation_angle(out.poses[static_cast<std::size_t>(k)].q, about_z(30.0 * k))) < 1e-14);
}

TEST_CASE("resample: irregular input rates give the same straight line") {
  Trace in;
  const double ts[] = {0.0, 0.013, 0.1, 0.35, 0.4, 0.41, 0.77, 1.0};
  for (double t : ts) in.poses.push_back(pose_at(t, {3.0 * t, 1.0, -2.0 * t}));
  ResampleReport rep;
  ResampleOptions o;
  o.fps = 10.0;
  const Trace out = resample(in, o, &rep);
  REQUIRE(out.poses.size() == 11);
  CHECK(rep.gaps == 0);
  CHECK(rep.longest_gap_s == doctest::Approx(0.36));
  for (const Pose& p : out.poses) {
    CHECK(std::abs(p.pos_m.x - 3.0 * p.t_s) < 4e-15);
    CHECK(std::abs(p.pos_m.z + 2.0 * p.t_s) < 4e-15);
  }
}

TEST_CASE("resample: gaps are counted - interpolate, hold or error") {
  Trace in;
  in.name = "gappy";
  in.poses = {pose_at(0.0, {0, 0, 0}), pose_at(0.1, {1, 0, 0}), pose_at(2.1, {21, 0, 0}),
              pose_at(2.2, {22, 0, 0})};
  ResampleOptions o;
  o.fps = 10.0;
  o.gap_s = 0.5;
  ResampleReport rep;
  const Trace interp = resample(in, o, &rep);
  CHECK(rep.gaps == 1);
  CHECK(rep.gap_time_s == doctest::Approx(2.0));
  CHECK(rep.frames == 23);
  CHECK(interp.poses[11].pos_m.x == doctest::Approx(11.0));  // t = 1.1, halfway through the gap

  o.gap_policy = GapPolicy::hold;
  const Trace hold = resample(in, o);
  for (int k = 1; k <= 20; ++k) CHECK(hold.poses[static_cast<std::size_t>(k)].pos_m.x == 1.0);
  CHECK(hold.poses[21].pos_m.x == doctest::Approx(21.0));  // t = 2.1: the pose after the gap

  o.gap_policy = GapPolicy::error;
  const std::string e = input_error([&] { resample(in, o); });
  CHECK(contains(e, "gappy pose 2"));
  CHECK(contains(e, "gap of 2 s"));
}

TEST_CASE("resample: frame times are closed-form and the last frame is not after the end") {
  Trace in;
  in.poses = {pose_at(5.0, {0, 0, 0}), pose_at(5.0 + 1.0 / 3.0, {1, 0, 0}), pose_at(25.0, {2, 0, 0})};
  const Trace out = resample(in, 60.0);
  REQUIRE(out.poses.size() == 1201);
  for (std::size_t k = 0; k < out.poses.size(); ++k) CHECK(out.poses[k].t_s == 5.0 + static_cast<double>(k) / 60.0);
  CHECK(out.poses.back().pos_m.x == 2.0);
  // An input pose exactly on a frame time is copied, not interpolated.
  CHECK(out.poses[20].pos_m.x == 1.0);
  // 0.95 s at 10 Hz: frames 0 .. 0.9.
  Trace short_in;
  short_in.poses = {pose_at(0.0, {0, 0, 0}), pose_at(0.95, {1, 0, 0})};
  CHECK(resample(short_in, 10.0).poses.size() == 10);
  // One pose: one frame.
  Trace single;
  single.poses = {pose_at(1.0, {1, 2, 3})};
  CHECK(resample(single, 60.0).poses.size() == 1);
}

TEST_CASE("sample_trace clamps outside and interpolates inside") {
  Trace in;
  in.poses = {pose_at(1.0, {0, 0, 0}), pose_at(2.0, {10, 0, 0})};
  CHECK(sample_trace(in, 0.0).pos_m.x == 0.0);
  CHECK(sample_trace(in, 9.0).pos_m.x == 10.0);
  CHECK(sample_trace(in, 1.25).pos_m.x == 2.5);
  CHECK(sample_trace(in, 2.0).pos_m.x == 10.0);
}

TEST_CASE("resample: bad options") {
  Trace in;
  in.poses = {pose_at(0.0, {0, 0, 0}), pose_at(1.0, {1, 0, 0})};
  ResampleOptions o;
  o.fps = 0.0;
  CHECK(contains(input_error([&] { resample(in, o); }), "fps"));
  o.fps = std::nan("");
  CHECK(contains(input_error([&] { resample(in, o); }), "fps"));
  o.fps = 60.0;
  o.gap_s = -1.0;
  CHECK(contains(input_error([&] { resample(in, o); }), "gap"));
  Trace huge;
  huge.poses = {pose_at(0.0, {0, 0, 0}), pose_at(1e6, {1, 0, 0})};
  CHECK(contains(input_error([&] { resample(huge, 10000.0); }), "exceed the limit"));
  Trace backwards;
  backwards.poses = {pose_at(1.0, {0, 0, 0}), pose_at(0.0, {1, 0, 0})};
  CHECK(contains(input_error([&] { resample(backwards, 60.0); }), "pose 1"));
}
