#include <doctest/doctest.h>

#include <cmath>

#include "core/error.h"
#include "core/camera.h"

using namespace vtsim;

namespace {
bool near3(const glm::dvec3& a, const glm::dvec3& b, double tol = 1e-12) {
  return std::fabs(a.x - b.x) <= tol && std::fabs(a.y - b.y) <= tol && std::fabs(a.z - b.z) <= tol;
}
}  // namespace

TEST_CASE("camera axes follow the FLU convention and yaw/pitch/roll") {
  const Camera id = make_camera(Pose{}, 1920, 1080);
  CHECK(near3(id.fwd, {1, 0, 0}));
  CHECK(near3(id.left, {0, 1, 0}));
  CHECK(near3(id.up, {0, 0, 1}));
  const Camera north = make_camera(pose_from_angles({0, 0, 0}, 90, 0), 1920, 1080);
  CHECK(near3(north.fwd, {0, 1, 0}));
  CHECK(near3(north.left, {-1, 0, 0}));
  const Camera down = make_camera(pose_from_angles({0, 0, 0}, 0, -90), 1920, 1080);
  CHECK(near3(down.fwd, {0, 0, -1}));
  CHECK(near3(down.up, {1, 0, 0}));  // image top points along the old heading
  const Camera up30 = make_camera(pose_from_angles({0, 0, 0}, 0, 30), 1920, 1080);
  CHECK(up30.fwd.z == doctest::Approx(0.5));
  const Camera rolled = make_camera(pose_from_angles({0, 0, 0}, 0, 0, 90), 1920, 1080);
  CHECK(near3(rolled.left, {0, 0, 1}));  // right side down: left points up
}

TEST_CASE("pixel rays: square pixels / centre on the axis / one pixel = one unit of left/up") {
  const Camera c = make_camera(pose_from_angles({1, 2, 3}, 37, -12, 5, 50), 1280, 720);
  CHECK(c.vfov_deg() == doctest::Approx(50.0));
  CHECK(c.hfov_deg() == doctest::Approx(2.0 * std::atan(1280.0 / 720.0 * std::tan(25.0 * M_PI / 180.0)) * 180.0 / M_PI));
  CHECK(near3(c.ray_dir(640.0, 360.0), c.focal_px * c.fwd, 1e-9));
  const glm::dvec3 d = c.ray_dir(100.5, 200.5);
  CHECK(glm::dot(d, c.fwd) == doctest::Approx(c.focal_px));
  CHECK(near3(c.ray_dir(101.5, 200.5) - d, -c.left, 1e-9));
  CHECK(near3(c.ray_dir(100.5, 201.5) - d, -c.up, 1e-9));
}

TEST_CASE("buffer geometry: ceil sizes and block-centre full-resolution pixels") {
  CHECK(buffer_extent(1920, 8) == 240);
  CHECK(buffer_extent(1921, 8) == 241);
  CHECK(buffer_extent(1, 16) == 1);
  CHECK(sample_pixel(0, 1, 10) == 0);
  CHECK(sample_pixel(9, 1, 10) == 9);
  CHECK(sample_pixel(0, 8, 1920) == 4);
  CHECK(sample_pixel(239, 8, 1920) == 1916);
  CHECK(sample_pixel(240, 8, 1921) == 1920);  // last block is the single pixel 1920
  CHECK(sample_pixel(1, 7, 10) == 8);         // block [7, 10): middle pixel 8
  CHECK(sample_pos(0, 8, 1920) == 4.5);
}

TEST_CASE("camera and view parameters reject bad input") {
  Pose p;
  CHECK_THROWS_AS(make_camera(p, 0, 1080), InputError);
  CHECK_THROWS_AS(make_camera(p, 1920, kMaxImageSide + 1), InputError);
  CHECK_THROWS_AS(make_camera(p, 1920, 1080, 0.0), InputError);
  CHECK_THROWS_AS(make_camera(p, 1920, 1080, 180.0), InputError);
  CHECK_THROWS_AS(make_camera(p, 1920, 1080, std::nan("")), InputError);
  p.pos_m.x = std::nan("");
  CHECK_THROWS_AS(make_camera(p, 1920, 1080), InputError);
  p = Pose{};
  p.q = glm::dquat(0, 0, 0, 0);
  CHECK_THROWS_AS(make_camera(p, 1920, 1080), InputError);
  p.q = glm::dquat(2, 0, 0, 0);  // unnormalised: normalised, accepted
  CHECK(near3(make_camera(p, 10, 10).fwd, {1, 0, 0}));

  ViewParams v;
  CHECK_NOTHROW(validate_view_params(v));
  v.divisor = 0;
  CHECK_THROWS_AS(validate_view_params(v), InputError);
  v = ViewParams{};
  v.lod_bias = std::nanf("");
  CHECK_THROWS_AS(validate_view_params(v), InputError);
  v = ViewParams{};
  v.max_aniso = 0.5f;
  CHECK_THROWS_AS(validate_view_params(v), InputError);
  v = ViewParams{};
  v.near_m = 0.0;
  CHECK_THROWS_AS(validate_view_params(v), InputError);
  v = ViewParams{};
  v.far_m = v.near_m;
  CHECK_THROWS_AS(validate_view_params(v), InputError);
  v.far_m = std::nan("");
  CHECK_THROWS_AS(validate_view_params(v), InputError);
}

TEST_CASE("trace poses by frame and by time") {
  Trace tr;
  Pose a, b;
  a.t_s = 1.0;
  a.pos_m = {0, 0, 0};
  b.t_s = 3.0;
  b.pos_m = {10, 0, 2};
  b.q = glm::angleAxis(M_PI / 2, glm::dvec3(0, 0, 1));
  b.vfov_deg = 80;
  tr.poses = {a, b};
  CHECK(trace_pose(tr, 1).pos_m.x == 10.0);
  CHECK_THROWS_AS(trace_pose(tr, 2), InputError);
  CHECK_THROWS_AS(trace_pose(tr, -1), InputError);
  const Pose m = trace_pose_at(tr, 2.0);
  CHECK(m.pos_m.x == doctest::Approx(5.0));
  CHECK(m.pos_m.z == doctest::Approx(1.0));
  CHECK(m.vfov_deg == doctest::Approx(70.0));
  CHECK(near3(make_camera(m, 10, 10).fwd, {std::sqrt(0.5), std::sqrt(0.5), 0}, 1e-12));
  CHECK(trace_pose_at(tr, -5.0).pos_m.x == 0.0);
  CHECK(trace_pose_at(tr, 99.0).pos_m.x == 10.0);
  CHECK_THROWS_AS(trace_pose_at(tr, std::nan("")), InputError);
  CHECK_THROWS_AS(trace_pose_at(Trace{}, 0.0), InputError);
}
