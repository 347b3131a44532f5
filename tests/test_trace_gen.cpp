// Generators: exact positions at given frames, speeds, events, reproducibility, bad parameters.
#include <doctest/doctest.h>

#include <cmath>
#include <numbers>

#include "sim/trace/trace_gen.h"
#include "sim/trace/trace_stats.h"
#include "trace_test_util.h"

using namespace vtsim;
using vtsim::test::contains;
using vtsim::test::input_error;
using vtsim::test::same_bits;

namespace {

using vtsim::test::kForward;
using vtsim::test::kUp;
constexpr double kPi = std::numbers::pi;

Trace gen(std::string_view k) { return generate_trace(default_gen_params(k)); }

// Positions near 4096 m carry ~1e-12 m of rounding, so a 1/60 s step's speed is good to ~1e-10.
void check_speed(const Trace& t, double v) {
  const TraceStats s = trace_stats(t);
  CHECK(s.speed_p50_mps == doctest::Approx(v).epsilon(1e-9));
  CHECK(s.speed_max_mps == doctest::Approx(v).epsilon(1e-9));
  CHECK(s.path_length_m == doctest::Approx(v * 20.0).epsilon(1e-12));
  CHECK(s.cuts == 0);
}

}  // namespace

TEST_CASE("walk: closed-form positions, 60 Hz for 20 s, eye height, pitch -15") {
  const Trace t = gen("walk");
  REQUIRE(t.poses.size() == 1201);
  CHECK(t.image_width == 1920);
  CHECK(t.image_height == 1080);
  CHECK(t.poses[60].t_s == 1.0);
  CHECK(t.poses[60].pos_m == glm::dvec3(4097.5, 4096.0, 1.7));
  CHECK(t.poses[1200].pos_m == glm::dvec3(4126.0, 4096.0, 1.7));
  for (std::size_t i = 0; i < t.poses.size(); ++i) {
    CHECK(t.poses[i].t_s == static_cast<double>(i) / 60.0);
    CHECK(same_bits(t.poses[i].pos_m.x, 4096.0 + 1.5 * (static_cast<double>(i) / 60.0)));
  }
  const glm::dvec3 f = t.poses[0].q * kForward;
  CHECK(f.x == doctest::Approx(std::cos(kPi / 12)));
  CHECK(f.z == doctest::Approx(-std::sin(kPi / 12)));
  CHECK(std::abs(f.y) < 1e-16);
  check_speed(t, 1.5);
}

TEST_CASE("walk_diagonal stays on x = y - run, drive and flight have their speeds and heights") {
  const Trace d = gen("walk_diagonal");
  for (const Pose& p : d.poses) CHECK(p.pos_m.x == p.pos_m.y);
  CHECK(d.poses[600].pos_m.x == 4096.0 + std::sqrt(0.5) * 15.0);
  check_speed(d, 1.5);
  const Trace r = gen("run");
  CHECK(r.poses[1200].pos_m == glm::dvec3(4196.0, 4096.0, 1.7));
  check_speed(r, 5.0);
  const Trace v = gen("drive");
  CHECK(v.poses[1200].pos_m == glm::dvec3(4496.0, 4096.0, 1.5));
  check_speed(v, 20.0);
  const Trace f = gen("flight");
  CHECK(f.poses[1200].pos_m == glm::dvec3(6096.0, 4096.0, 300.0));
  CHECK((f.poses[0].q * kForward).z == doctest::Approx(-0.5));  // pitch -30
  check_speed(f, 100.0);
}

TEST_CASE("turn: 180 degrees in 0.5 s at 10 s while walking") {
  const Trace t = gen("turn");
  REQUIRE(t.poses.size() == 1201);
  CHECK((t.poses[600].q * kForward).x > 0.96);   // t = 10: the turn starts
  CHECK((t.poses[630].q * kForward).x < -0.96);  // t = 10.5: turned around
  CHECK(t.poses[599].pos_m == glm::dvec3(4096.0 + 1.5 * (599.0 / 60.0), 4096.0, 1.7));
  // After the turn it walks back: 15 m out, a half circle of radius v / w = 1.5 / (2 pi) m,
  // then 9.5 s back.
  const double radius = 1.5 / (2.0 * kPi);
  CHECK(t.poses[1200].pos_m.x == doctest::Approx(4096.0 + 15.0 - 14.25).epsilon(1e-13));
  CHECK(t.poses[1200].pos_m.y == doctest::Approx(4096.0 + 2.0 * radius).epsilon(1e-13));
  const TraceStats s = trace_stats(t);
  CHECK(s.angular_speed_max_dps == doctest::Approx(360.0).epsilon(1e-9));
  CHECK(s.speed_max_mps <= 1.5 + 1e-9);
  CHECK(s.speed_p50_mps == doctest::Approx(1.5).epsilon(1e-9));
  // A clockwise turn mirrors the path.
  TraceGenParams p = default_gen_params("turn");
  p.turn_deg = -180.0;
  const Trace m = generate_trace(p);
  CHECK(m.poses[1200].pos_m.y == doctest::Approx(4096.0 - 2.0 * radius).epsilon(1e-13));
}

TEST_CASE("teleport: one cut of 2 km between frames 599 and 600") {
  const Trace t = gen("teleport");
  CHECK(t.poses[599].pos_m.y == 4096.0);
  CHECK(t.poses[600].pos_m == glm::dvec3(4096.0 + 15.0, 6096.0, 1.7));
  const TraceStats s = trace_stats(t);
  REQUIRE(s.cuts == 1);
  CHECK(s.cut_list[0].pose == 600);
  CHECK(s.cut_distance_max_m == doctest::Approx(std::hypot(2000.0, 0.025)));
  CHECK(s.speed_max_mps == doctest::Approx(1.5).epsilon(1e-9));  // the cut is not a speed
  CHECK(s.path_length_m == doctest::Approx(1199 * 0.025).epsilon(1e-12));
}

TEST_CASE("orbit: on the circle, looking at the centre's foot, one lap in 20 s") {
  const Trace t = gen("orbit");
  const glm::dvec2 c(4096.0, 4096.0);
  for (std::size_t i = 0; i < t.poses.size(); i += 37) {
    const Pose& p = t.poses[i];
    CHECK(std::hypot(p.pos_m.x - c.x, p.pos_m.y - c.y) == doctest::Approx(50.0).epsilon(1e-12));
    CHECK(p.pos_m.z == 30.0);
    const glm::dvec3 f = p.q * kForward;
    const double s = -p.pos_m.z / f.z;  // ray to the ground plane
    CHECK(std::abs(p.pos_m.x + s * f.x - c.x) < 1e-9);
    CHECK(std::abs(p.pos_m.y + s * f.y - c.y) < 1e-9);
    CHECK((p.q * kUp).z > 0.0);  // upright
  }
  // Starts west of the centre looking east (heading 0); ends where it started.
  CHECK(t.poses[0].pos_m.x == doctest::Approx(4046.0));
  CHECK(std::abs(t.poses[1200].pos_m.x - t.poses[0].pos_m.x) < 1e-9);
  CHECK(std::abs(t.poses[1200].pos_m.y - t.poses[0].pos_m.y) < 1e-9);
  const TraceStats s = trace_stats(t);
  // Chord over arc for 1/1200 of a lap: speed is 5 pi m/s times sin(x)/x, x = pi / 1200.
  const double x = kPi / 1200.0;
  CHECK(s.speed_p50_mps == doctest::Approx(5.0 * kPi * std::sin(x) / x).epsilon(1e-9));
}

TEST_CASE("static: no motion") {
  const Trace t = gen("static");
  CHECK(trace_generators().find("static") != nullptr);
  REQUIRE(t.poses.size() == 1201);
  for (const Pose& p : t.poses) CHECK(p.pos_m == glm::dvec3(4096.0, 4096.0, 1.7));
  const TraceStats s = trace_stats(t);
  CHECK(s.speed_max_mps == 0.0);
  CHECK(s.angular_speed_max_dps == 0.0);
}

TEST_CASE("generation is reproducible and exact far into a long trace") {
  TraceGenParams p = default_gen_params("walk");
  p.duration_s = 600.0;
  const Trace a = generate_trace(p), b = generate_trace(p);
  REQUIRE(a.poses.size() == 36001);
  CHECK(a.poses[36000].pos_m.x == 4996.0);
  CHECK(a.poses[36000].t_s == 600.0);
  for (std::size_t i = 0; i < a.poses.size(); ++i) REQUIRE(same_bits(a.poses[i].pos_m.x, b.poses[i].pos_m.x));
  // A walk due north does not drift east.
  p.heading_deg = 90.0;
  const Trace n = generate_trace(p);
  CHECK(n.poses[36000].pos_m == glm::dvec3(4096.0, 4996.0, 1.7));
  // Parameters show up in the name.
  CHECK(contains(n.name, "walk duration_s=600"));
}

TEST_CASE("generator parameters out of range name the field") {
  struct Case {
    const char* field;
    const char* kind;
    void (*set)(TraceGenParams&);
  };
  const Case cases[] = {
      {"duration_s", "walk", [](TraceGenParams& p) { p.duration_s = -1; }},
      {"fps", "walk", [](TraceGenParams& p) { p.fps = 0; }},
      {"duration_s", "walk", [](TraceGenParams& p) { p.duration_s = 1e6; p.fps = 1000; }},
      {"speed_mps", "run", [](TraceGenParams& p) { p.speed_mps = std::nan(""); }},
      {"pitch_deg", "walk", [](TraceGenParams& p) { p.pitch_deg = 91; }},
      {"vfov_deg", "walk", [](TraceGenParams& p) { p.vfov_deg = 0; }},
      {"image_width", "walk", [](TraceGenParams& p) { p.image_width = 0; }},
      {"event_s", "turn", [](TraceGenParams& p) { p.event_s = 30; }},
      {"turn_s", "turn", [](TraceGenParams& p) { p.turn_s = 0; }},
      {"jump_m", "teleport", [](TraceGenParams& p) { p.jump_m = -5; }},
      {"radius_m", "orbit", [](TraceGenParams& p) { p.radius_m = 0; }},
      {"start_m", "walk", [](TraceGenParams& p) { p.start_m.x = INFINITY; }},
  };
  for (const Case& c : cases) {
    CAPTURE(c.field);
    TraceGenParams p = default_gen_params(c.kind);
    c.set(p);
    CHECK(contains(input_error([&] { generate_trace(p); }), std::string(c.field) + ":"));
  }
  CHECK(contains(input_error([] { find_trace_generator("fly", "kind"); }), "walk, walk_diagonal"));
  CHECK(contains(input_error([] { find_trace_generator("fligt", "kind"); }), "did you mean 'flight'?"));
  CHECK(find_trace_generator("static", "kind").name == "static");
}
