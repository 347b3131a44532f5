// trace_stats: hand-computed figures, and the three full real recordings against an independent
// Python computation.
#include <doctest/doctest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>

#include "sim/trace/trace_import.h"
#include "sim/trace/trace_stats.h"
#include "trace_test_util.h"

using namespace vtsim;

namespace {

Pose pose_at(double t, double x, double yaw_deg = 0.0) {
  Pose p;
  p.t_s = t;
  p.pos_m = {x, 0.0, 0.0};
  const double h = yaw_deg * std::numbers::pi / 360.0;
  p.q = {std::cos(h), 0.0, 0.0, std::sin(h)};
  return p;
}

// A 1 ms step (merged for speeds), a 7 s gap, a 100 m cut in 10 ms.
Trace hand_trace() {
  Trace t;
  t.poses = {pose_at(0, 0),        pose_at(1, 1, 10),   pose_at(2, 3, 10),   pose_at(2.001, 3.01, 10),
             pose_at(3, 4, 10),    pose_at(10, 11, 10), pose_at(10.01, 111, 10), pose_at(11, 112, 10)};
  return t;
}

}  // namespace

TEST_CASE("trace_stats on a hand-made trace") {
  TraceStatsOptions o;
  o.gap_s = 2.0;  // the 1 s steps are not gaps here
  const TraceStats s = trace_stats(hand_trace(), o);
  CHECK(s.frames == 8);
  CHECK(s.duration_s == 11.0);
  CHECK(s.mean_rate_hz == doctest::Approx(7.0 / 11.0));
  CHECK(s.dt_min_s == doctest::Approx(0.001));
  CHECK(s.dt_max_s == 7.0);
  CHECK(s.path_length_m == doctest::Approx(12.0));  // 1 + 2 + 0.01 + 0.99 + 7 + (cut) + 1
  // Speed steps: 0-1: 1, 1-2: 2, 2-4 (the 1 ms step merged): 1, 4-5: 1, 6-7: 1/0.99.
  CHECK(s.speed_steps == 5);
  CHECK(s.speed_p50_mps == doctest::Approx(1.0));
  CHECK(s.speed_p99_mps == doctest::Approx(2.0));
  CHECK(s.speed_max_mps == doctest::Approx(2.0));
  CHECK(s.angular_speed_max_dps == doctest::Approx(10.0));
  CHECK(s.bbox_min_m == glm::dvec3(0, 0, 0));
  CHECK(s.bbox_max_m == glm::dvec3(112, 0, 0));
  REQUIRE(s.cuts == 1);
  CHECK(s.cut_list[0].pose == 6);
  CHECK(s.cut_distance_max_m == doctest::Approx(100.0));
  REQUIRE(s.gaps == 1);
  CHECK(s.gap_list[0].pose == 5);
  CHECK(s.gap_list[0].dt_s == 7.0);
  // Raw steps: the 1 ms step counts as 10 m/s.
  TraceStatsOptions raw = o;
  raw.min_step_s = 0.0;
  const TraceStats r = trace_stats(hand_trace(), raw);
  CHECK(r.speed_steps == 6);
  CHECK(r.speed_max_mps == doctest::Approx(10.0));
  // Thresholds are options.
  CHECK(trace_stats(hand_trace()).gaps == 5);  // the default 0.5 s: every step of 0.99 s or more
  TraceStatsOptions loose;
  loose.cut_speed_mps = 1e5;
  loose.gap_s = 10.0;
  const TraceStats l = trace_stats(hand_trace(), loose);
  CHECK(l.cuts == 0);
  CHECK(l.gaps == 0);
  CHECK(l.speed_max_mps == doctest::Approx(100.0 / 0.01));
}

TEST_CASE("trace_stats: one pose, and JSON") {
  Trace t;
  t.poses = {pose_at(3, 1)};
  const TraceStats s = trace_stats(t);
  CHECK(s.frames == 1);
  CHECK(s.duration_s == 0.0);
  CHECK(s.mean_rate_hz == 0.0);
  CHECK(s.speed_max_mps == 0.0);
  const nlohmann::json j = to_json(trace_stats(hand_trace()));
  CHECK(j["frames"] == 8);
  CHECK(j["cuts"] == 1);
  CHECK(j["cut_list"][0]["pose"] == 6);
  CHECK(j["bbox_max_m"][0] == 112.0);
  CHECK(j.contains("speed_p99_mps"));
  CHECK(j.contains("angular_speed_max_dps"));
}

// Reference figures for the full recordings in /work/shared/traces-real/, computed from the raw
// files by tests/data/reference_trace_stats.py (Python standard library only, no vtsim code):
//   $ python3 tests/data/reference_trace_stats.py
//   tum_fr1_xyz_groundtruth.txt: frames=3000 duration_s=30.0896 path_length_m=9.159267877342058 speed_max_mps=0.6010823570860686
//   tum_fr2_desk_groundtruth.txt: frames=20956 duration_s=99.3645 path_length_m=20.338724912715975 speed_max_mps=1.152105437350935
//   euroc_V1_02_groundtruth.csv: frames=16702 duration_s=83.504999936 path_length_m=75.89131656927523 speed_max_mps=2.1944649801121994
TEST_CASE("trace info figures of the three full real recordings match the Python reference") {
  struct Ref {
    const char* file;
    std::int64_t frames;
    double duration_s, path_length_m, speed_max_mps;
  };
  const Ref refs[] = {
      {"tum_fr1_xyz_groundtruth.txt", 3000, 30.0896, 9.159267877342058, 0.6010823570860686},
      {"tum_fr2_desk_groundtruth.txt", 20956, 99.3645, 20.338724912715975, 1.152105437350935},
      {"euroc_V1_02_groundtruth.csv", 16702, 83.504999936, 75.89131656927523, 2.1944649801121994},
  };
  // The recordings live beside the checkout (../shared, as in CI), not in the repository: a clone
  // without them skips this case loudly instead of failing the README's test command.
  const std::string dir = std::string(VTSIM_SHARED_DIR) + "/traces-real";
  if (!std::ifstream(dir + "/" + refs[0].file).good()) {
    MESSAGE("skipped: " << dir << " is absent (full real recordings; CI has them)");
    return;
  }
  for (const Ref& r : refs) {
    CAPTURE(r.file);
    const std::string path = dir + "/" + r.file;
    REQUIRE(std::ifstream(path).good());
    TraceLoadReport rep;
    const Trace t = import_trace(path, {}, &rep);
    const TraceStats s = trace_stats(t);
    CHECK(s.frames == r.frames);
    CHECK(s.duration_s == doctest::Approx(r.duration_s).epsilon(1e-12));
    CHECK(s.path_length_m == doctest::Approx(r.path_length_m).epsilon(1e-12));
    CHECK(s.speed_max_mps == doctest::Approx(r.speed_max_mps).epsilon(1e-12));
    CHECK(s.cuts == 0);
  }
}
