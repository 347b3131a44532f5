#include <doctest/doctest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>

#include "core/error.h"
#include "level_test_util.h"
#include "sim/trace/trace_io.h"
#include "sim/view/level_walk.h"
#include "test_util.h"

using namespace vtsim;

namespace {

// Segment a-b against triangle (Moeller & Trumbore), both faces; t in (0, 1].
bool lwt_segment_hits(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& p0, const glm::dvec3& p1,
                      const glm::dvec3& p2) {
  const glm::dvec3 d = b - a, e1 = p1 - p0, e2 = p2 - p0, pv = glm::cross(d, e2);
  const double det = glm::dot(e1, pv);
  if (det == 0.0) return false;
  const glm::dvec3 tv = a - p0;
  const double u = glm::dot(tv, pv) / det;
  if (u < 0 || u > 1) return false;
  const glm::dvec3 qv = glm::cross(tv, e1);
  const double v = glm::dot(d, qv) / det, t = glm::dot(e2, qv) / det;
  return v >= 0 && u + v <= 1 && t > 0 && t <= 1;
}

bool lwt_same(const Trace& a, const Trace& b) {
  if (a.poses.size() != b.poses.size() || a.name != b.name) return false;
  for (std::size_t i = 0; i < a.poses.size(); ++i)
    if (std::memcmp(&a.poses[i], &b.poses[i], sizeof(Pose)) != 0) return false;
  return true;
}

double lwt_yaw_deg(const glm::dquat& q) {
  const glm::dvec3 f = q * glm::dvec3(1, 0, 0);
  return std::atan2(f.y, f.x) * 180.0 / 3.14159265358979323846;
}

}  // namespace

TEST_CASE("level walk: a tour of two rooms through the door, at eye height, never through a wall") {
  const Mesh m = test::two_room_level();
  LevelWalkParams p;
  LevelWalkStats st;
  const Trace t = level_walk(m, test::two_room_waypoints(), p, &st);
  CHECK(st.waypoints == 6);
  CHECK(st.no_floor == 1);     // (30, 30): outside the level
  CHECK(st.unreachable == 1);  // on the pedestal: a 1 m step
  CHECK(st.no_floor_list == std::vector<std::size_t>{5});
  CHECK(st.unreachable_list == std::vector<std::size_t>{4});
  CHECK(st.visited == 4);
  REQUIRE(st.order.size() == 4);
  CHECK(st.order[0] == 0);
  CHECK(st.legs >= 3);
  REQUIRE(t.poses.size() > 100);
  CHECK(st.tour_s == doctest::Approx(st.path_length_m / p.speed_mps));  // a flat floor: 3-D = horizontal length
  bool in_b = false;
  for (std::size_t i = 0; i < t.poses.size(); ++i) {
    const Pose& ps = t.poses[i];
    CHECK(ps.t_s == static_cast<double>(i) / p.fps);
    CHECK(ps.pos_m.z == 1.7);  // floor z = 0 everywhere: exact
    in_b = in_b || ps.pos_m.x > 6.0;
    if (i == 0) continue;
    const glm::dvec3 a = t.poses[i - 1].pos_m, b = ps.pos_m;
    CHECK(glm::length(b - a) <= p.speed_mps / p.fps * (1 + 1e-9));
    for (const Mesh::Tri& tr : m.tris)
      REQUIRE_FALSE(lwt_segment_hits(a, b, m.positions[tr.p[0]], m.positions[tr.p[1]], m.positions[tr.p[2]]));
    // The heading turns at most max_turn_dps.
    const double dyaw = std::remainder(lwt_yaw_deg(ps.q) - lwt_yaw_deg(t.poses[i - 1].q), 360.0);
    CHECK(std::abs(dyaw) <= p.max_turn_dps / p.fps + 1e-6);
  }
  CHECK(in_b);
  // Deterministic: a second run is equal bit for bit.
  CHECK(lwt_same(t, level_walk(m, test::two_room_waypoints(), p)));
}

TEST_CASE("level walk: steps are climbed and the eye stays near eye height above the floor") {
  const Mesh m = test::two_room_level(true);
  LevelWalkParams p;
  LevelWalkStats st;
  const Trace t = level_walk(m, test::two_room_waypoints(), p, &st);
  CHECK(st.visited == 4);
  bool on_step = false;
  for (const Pose& ps : t.poses) {
    const bool over = ps.pos_m.x > 2.0 && ps.pos_m.x < 3.0;
    const double floor = over ? 0.3 : 0.0;
    // The eye follows the floor averaged over smooth_m: within the step height of eye_m above it.
    CHECK(ps.pos_m.z >= floor + p.eye_m - 0.3 - 1e-9);
    CHECK(ps.pos_m.z <= floor + p.eye_m + 0.3 + 1e-9);
    on_step = on_step || (over && std::abs(ps.pos_m.z - 2.0) < 1e-9);
  }
  CHECK(on_step);
}

TEST_CASE("level walk: a duration longer than the tour walks it back and forth, a shorter one cuts it") {
  const Mesh m = test::two_room_level();
  LevelWalkParams p;
  LevelWalkStats st;
  const Trace one = level_walk(m, test::two_room_waypoints(), p, &st);
  p.duration_s = 2.5 * st.tour_s;
  const Trace two = level_walk(m, test::two_room_waypoints(), p);
  CHECK(two.poses.size() == static_cast<std::size_t>(std::floor(p.duration_s * p.fps + 1e-6)) + 1);
  const std::size_t back = static_cast<std::size_t>(std::floor(st.tour_s * p.fps));
  CHECK(two.poses[back].pos_m == one.poses[back].pos_m);
  CHECK(glm::length(two.poses[2 * back].pos_m - one.poses[0].pos_m) < 0.05);  // back at the start
  p.duration_s = 1.0;
  CHECK(level_walk(m, test::two_room_waypoints(), p).poses.size() == 61);
}

TEST_CASE("level walk: a path walked in order, and a blocked leg or too few waypoints is an InputError") {
  const Mesh m = test::two_room_level();
  LevelWalkParams p;
  p.in_order = true;
  const std::vector<glm::dvec3> ok = {{1, 1, 0.6}, {4, 2.5, 0.6}, {7, 2.5, 0.6}, {10, 4, 0.6}};
  LevelWalkStats st;
  const Trace t = level_walk(m, ok, p, &st);
  CHECK(st.visited == 4);
  CHECK(st.legs == 3);
  CHECK(t.poses.back().pos_m.x == doctest::Approx(10).epsilon(1e-3));
  const auto refused = [&](const std::vector<glm::dvec3>& w, const LevelWalkParams& q, const std::string& what) {
    try {
      level_walk(m, w, q);
      FAIL("expected InputError");
    } catch (const InputError& e) {
      CAPTURE(e.what());
      CHECK(test::contains(e.what(), what));
    }
  };
  refused({{1, 1, 0.6}, {10, 1, 0.6}}, p, "waypoint 1 -> 2: not walkable straight");
  refused({{1, 1, 0.6}, {30, 30, 0.6}}, p, "waypoint 2 (30, 30, 0.6): no floor");
  refused({{1, 1, 0.6}}, p, "1 waypoint(s): a walk needs at least 2");
  LevelWalkParams tour;
  refused({{1, 4, 1.6}, {1, 1, 0.6}, {30, 30, 0.6}}, tour, "no two of the 3 waypoints");
  tour.speed_mps = -1;
  refused(test::two_room_waypoints(), tour, "speed_mps = -1");
  tour = LevelWalkParams{};
  tour.via_grid_m = 0.1;
  refused(test::two_room_waypoints(), tour, "via_grid_m = 0.1 is not 0 or in [0.25, 1000]");
  Mesh huge = m;
  test::level_add_quad(huge, {0, 0, 0}, {1e8, 0, 0}, {1e8, 1, 0}, {0, 1, 0});
  try {
    level_walk(huge, test::two_room_waypoints(), LevelWalkParams{});
    FAIL("expected InputError");
  } catch (const InputError& e) {
    CHECK(test::contains(e.what(), "spans more than 10,000 km"));
  }
}

TEST_CASE("level walk: via points join waypoints that no straight leg joins") {
  const Mesh m = test::two_room_level();
  const std::vector<glm::dvec3> w = {{4, 0.5, 0.6}, {7, 4.5, 0.6}};  // the dividing wall between them
  LevelWalkParams p;
  LevelWalkStats st;
  const Trace t = level_walk(m, w, p, &st);
  CHECK(st.visited == 2);
  CHECK(st.via_points > 0);
  CHECK(glm::length(glm::dvec2(t.poses.back().pos_m) - glm::dvec2(7, 4.5)) <= p.speed_mps / p.fps);  // the last frame
  for (std::size_t i = 1; i < t.poses.size(); ++i)
    for (const Mesh::Tri& tr : m.tris)
      REQUIRE_FALSE(lwt_segment_hits(t.poses[i - 1].pos_m, t.poses[i].pos_m, m.positions[tr.p[0]],
                                     m.positions[tr.p[1]], m.positions[tr.p[2]]));
  p.via_grid_m = 0.0;
  CHECK_THROWS_WITH_AS(level_walk(m, w, p), doctest::Contains("no two of the 2 waypoints"), InputError);
}

TEST_CASE("level walk: the CLI walks a level's spawn points and items through an OBJ mesh") {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / "vtsim_lw_cli";
  fs::create_directories(dir);
  // The two-room level in Quake units (--unit-m 0.0254), its entities in a .bsp.
  const Mesh m = test::two_room_level();
  std::string obj;
  for (const auto& q : m.positions) obj += "v " + std::to_string(q.x / 0.0254) + " " + std::to_string(q.y / 0.0254) + " " +
                                           std::to_string(q.z / 0.0254) + "\n";
  for (const auto& tr : m.tris)
    obj += "f " + std::to_string(tr.p[0] + 1) + " " + std::to_string(tr.p[1] + 1) + " " + std::to_string(tr.p[2] + 1) + "\n";
  std::ofstream(dir / "level.obj") << obj;
  std::string ents;
  for (const auto& w : test::two_room_waypoints())
    ents += "{ \"classname\" \"info_player_deathmatch\" \"origin\" \"" + std::to_string(w.x / 0.0254) + " " +
            std::to_string(w.y / 0.0254) + " " + std::to_string(w.z / 0.0254) + "\" }\n";
  std::ofstream(dir / "level.bsp", std::ios::binary) << test::make_q3_bsp(ents);
  const std::string out = (dir / "walk.csv").string();
  const test::CliRun r = test::run_vtsim_capture(
      "trace level-walk " + (dir / "level.bsp").string() + " --mesh " + (dir / "level.obj").string() + " -o " + out,
      (dir / "err.txt").string());
  CAPTURE(r.err);
  CHECK(r.code == 0);
  CHECK(test::contains(r.err, "6 waypoints (6 spawns, 0 items, 0 others), 4 visited"));
  CHECK(test::contains(r.err, "warning: 1 of 6 waypoints have no floor within 3 m below them, left out: "
                                      "info_player_deathmatch (30.00, 30.00, 0.60) m"));
  CHECK(test::contains(test::slurp(out), "level_walk waypoints=6 visited=4"));
  const test::CliRun bad = test::run_vtsim_capture("trace level-walk --mesh " + (dir / "level.obj").string() + " -o " + out,
                                                   (dir / "err.txt").string());
  CHECK(bad.code == 2);
  CHECK(test::contains(bad.err, "give a level (.bsp or .pk3) or --waypoints FILE"));
}

TEST_CASE("level walk: waypoint files") {
  const std::string path = (std::filesystem::temp_directory_path() / "vtsim_lw_waypoints.txt").string();
  std::ofstream(path) << "# x y z\n1 1 0.6\n\n4,2.5,0.6  # door\n";
  const auto w = read_waypoints(path);
  REQUIRE(w.size() == 2);
  CHECK(w[1] == glm::dvec3(4, 2.5, 0.6));
  std::ofstream(path) << "1 1 0.6\n1 2\n";
  CHECK_THROWS_WITH_AS(read_waypoints(path), doctest::Contains((path + ":2").c_str()), InputError);
  std::ofstream(path) << "1 1 x\n";
  CHECK_THROWS_WITH_AS(read_waypoints(path), doctest::Contains((path + ":1").c_str()), InputError);
}

TEST_CASE("level walk: the CLI reads a Quake 3 .pk3 mesh through the importer (scaled by --unit-m, z up)") {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("vtsim_lw_pk3_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  // tests/data/make_quad_q3_pk3.py: one 64 × 32-unit quad at z = 8 units = 0.2032 m, 1.63 × 0.81 m.
  const std::string pk3 = std::string(VTSIM_TEST_DATA) + "/quad_q3.pk3";
  std::ofstream(dir / "wp.txt") << "0.3 0.3 0.5\n1.3 0.5 0.5\n";
  const std::string out = (dir / "walk.csv").string();
  const test::CliRun r = test::run_vtsim_capture(
      "trace level-walk --waypoints " + (dir / "wp.txt").string() + " --mesh " + pk3 + " -o " + out,
      (dir / "err.txt").string());
  CAPTURE(r.err);
  REQUIRE(r.code == 0);
  CHECK(test::contains(r.err, "2 visited"));
  const Trace t = load_trace(out);
  REQUIRE(t.poses.size() > 2);
  for (const Pose& p : t.poses) CHECK(p.pos_m.z == doctest::Approx(8 * 0.0254 + 1.7).epsilon(1e-9));
  // A mesh file that is not there: exit 2, the file named.
  const test::CliRun missing = test::run_vtsim_capture(
      "trace level-walk --waypoints " + (dir / "wp.txt").string() + " --mesh " + (dir / "none.pk3").string() + " -o " + out,
      (dir / "err.txt").string());
  CHECK(missing.code == 2);
  CHECK(test::contains(missing.err, "none.pk3"));
  fs::remove_all(dir);
}
