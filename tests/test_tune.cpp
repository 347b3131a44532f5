// vtsim tune (sim/sweep/tune.h): the search finds the brute-force Pareto set with fewer replays,
// and catches monotonicity failures next to the front.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "core/error.h"
#include "sim/sweep/sweep.h"
#include "sim/sweep/tune.h"
#include "store_test_util.h"
#include "test_util.h"

using namespace vtsim;

namespace {

// A 6 × 6 × 4 grid of cost axes (the values only index the grid here).
const char* kGridSpec = R"(generate = ["walk duration_s=1"]
[grid]
"vt.pool_pages" = [64, 128, 256, 512, 1024, 2048]
"upload.tiles_per_frame" = [1, 2, 4, 8, 16, 32]
"ram.capacity_MiB" = [16, 32, 64, 128]
[tune]
constraints = ["m <= 0.5"]
)";

SweepSpec grid_spec(const test::TempDir& d, const std::string& text) {
  std::ofstream(d.file("spec.toml")) << text;
  return load_sweep_spec(d.file("spec.toml"));
}

// Rows whose metric "m" is f(i, j, k) of the grid indices; counts the configs replayed.
struct Fake {
  const SweepSpec& spec;
  std::function<double(int, int, int)> f;
  std::size_t replays = 0;
  std::vector<std::vector<nlohmann::json>> operator()(const std::vector<int>& configs) {
    std::vector<std::vector<nlohmann::json>> out;
    for (int p : configs) {
      ++replays;
      const int i = p / 24, j = (p / 4) % 6, k = p % 4;
      out.push_back({{{"status", "ok"}, {"trace", 0}, {"summary", {{"m", f(i, j, k)}}}}});
    }
    return out;
  }
  std::vector<int> brute() {
    std::vector<bool> pass;
    for (int p = 0; p < 144; ++p) pass.push_back(judge(spec.tune, (*this)({p})[0]).pass);
    return brute_force_front(spec, pass);
  }
};

}  // namespace

TEST_CASE("tune: on monotone constraints the search finds the brute-force front with at most a quarter of the grid") {
  test::TempDir d;
  const SweepSpec spec = grid_spec(d, kGridSpec);
  REQUIRE(spec.points.size() == 144);
  REQUIRE(spec.tune.costs.size() == 3);
  const std::vector<std::function<double(int, int, int)>> fs = {
      [](int i, int j, int k) { return 1.0 - (i + 2 * j + 3 * k) / 10.0; },            // a diagonal plane
      [](int i, int j, int) { return i >= 3 && j >= 2 ? 0.0 : 1.0; },                  // one corner, RAM free
      [](int i, int j, int k) { return 1.0 / (1.0 + i * j + k); },                     // a hyperbola
      [](int, int, int) { return 1.0; },                                               // nothing passes
      [](int, int, int) { return 0.0; },                                               // everything passes
  };
  for (std::size_t n = 0; n < fs.size(); ++n) {
    CAPTURE(n);
    Fake fake{spec, fs[n]};
    const TuneResult r = run_tune(spec, std::ref(fake));
    CHECK(r.monotonicity_failures.empty());
    CHECK(fake.replays == r.replayed.size());
    CHECK(r.replayed.size() <= 144 / 4);
    CHECK(r.front == fake.brute());
  }
}

TEST_CASE("tune: a config next to the front that passes against monotonicity is reported, and the front includes it") {
  test::TempDir d;
  const SweepSpec spec = grid_spec(d, kGridSpec);
  // i + j + k >= 5 passes, but (2, 1, 1) passes too while the dearer (2, 2, 1) fails: the walk
  // meets the failure and assumes everything cheaper in that column fails; the check of the front
  // config (3, 1, 1) replays its neighbour (2, 1, 1) and finds it passing.
  Fake fake{spec, [](int i, int j, int k) {
              const bool hole = i == 2 && j == 1 && k == 1, dent = i == 2 && j == 2 && k == 1;
              return (hole || i + j + k >= 5) && !dent ? 0.0 : 1.0;
            }};
  const TuneResult r = run_tune(spec, std::ref(fake));
  const int hole = 2 * 24 + 1 * 4 + 1;
  CHECK(r.monotonicity_failures == std::vector<int>{hole});
  CHECK(r.front == fake.brute());
  CHECK(std::find(r.front.begin(), r.front.end(), hole) != r.front.end());
  for (int p : r.front) CHECK(r.replayed.at(p).pass);
}

TEST_CASE("tune: spec errors for [tune] name the file and line") {
  test::TempDir d;
  CHECK_THROWS_WITH_AS(grid_spec(d, "generate = [\"walk\"]\n[grid]\n\"vt.pool_pages\" = [1]\n[tune]\nconstraints = [\"m < 3\"]\n"),
                       doctest::Contains("spec.toml:5: tune constraint 'm < 3' is not"), InputError);
  CHECK_THROWS_WITH_AS(grid_spec(d, "generate = [\"walk\"]\n[grid]\n\"vt.pool_pages\" = [1]\n[tune]\ncosts = [\"ram.capacity_MiB\"]\n"),
                       doctest::Contains("'ram.capacity_MiB' is not a [grid] axis"), InputError);
  CHECK_THROWS_WITH_AS(grid_spec(d, "generate = [\"walk\"]\n[grid]\n\"vt.pool_pages\" = [1]\n[tune]\nbudget = 3\n"),
                       doctest::Contains("unknown key 'tune.budget'"), InputError);
  const SweepSpec no_tune = grid_spec(d, "generate = [\"walk\"]\n[grid]\n\"vt.pool_pages\" = [1]\n");
  CHECK_THROWS_AS(run_tune(no_tune, [](const std::vector<int>&) { return std::vector<std::vector<nlohmann::json>>{}; }), InputError);
}

TEST_CASE("tune CLI: a constraint on no summary value or a store that does not open is refused before any replay") {
  test::TempDir d;
  std::ofstream(d.file("bad.toml")) << "generate = [\"walk duration_s=1\"]\n[grid]\n\"upload.tiles_per_frame\" = [1, 4]\n"
                                       "[tune]\nconstraints = [\"latency_ms.p99 <= 200\", \"popin.blurry <= 0.1\"]\n";
  test::CliRun r = test::run_vtsim_capture("tune " + d.file("bad.toml") + " -o " + d.file("o1"), d.file("err"));
  CHECK(r.code == 2);
  CHECK(test::contains(r.err, d.file("bad.toml") + ":5: tune.constraints: 'popin.blurry' is not a value of a replay summary"));
  CHECK_FALSE(std::filesystem::exists(d.file("o1")));
  std::ofstream(d.file("ok.toml")) << "generate = [\"walk duration_s=1\"]\n[grid]\n\"upload.tiles_per_frame\" = [1, 4]\n"
                                      "[tune]\nconstraints = [\"latency_ms.p99 <= 200\"]\n";
  r = test::run_vtsim_capture("tune " + d.file("ok.toml") + " -o " + d.file("o2") + " --store " + d.file("none.vts"), d.file("err"));
  CHECK(r.code == 2);
  CHECK(test::contains(r.err, d.file("none.vts") + ": cannot open"));
  CHECK_FALSE(test::contains(r.err, "replayed"));
  CHECK_FALSE(std::filesystem::exists(d.file("o2")));
}

TEST_CASE("tune: on real replays the search equals the brute-force front of the same grid") {
  test::TempDir d;
  const SweepSpec spec = grid_spec(d, R"(set = ["view.divisor=16"]
generate = ["walk duration_s=2", "turn duration_s=2 event_s=1"]
[grid]
"upload.tiles_per_frame" = [1, 2, 4, 8]
"ram.capacity_MiB" = [1, 4, 16]
[tune]
constraints = ["popin.blurry_fraction_mean <= 0.5", "latency_ms.p99 <= 200"]
)");
  const std::vector<Trace> traces = load_sweep_traces(spec);
  std::size_t replays = 0;
  const TuneResult r = run_tune(spec, [&](const std::vector<int>& c) {
    replays += c.size();
    return replay_points(spec, traces, c, 1);
  });
  std::vector<int> all(spec.points.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  const auto rows = replay_points(spec, traces, all, 2);
  std::vector<bool> pass;
  for (const auto& rr : rows) pass.push_back(judge(spec.tune, rr).pass);
  CHECK(r.front == brute_force_front(spec, pass));
  CHECK(replays == r.replayed.size());
  CHECK(r.replayed.size() < spec.points.size());
  for (const auto& [p, v] : r.replayed) CHECK(v.pass == pass[static_cast<std::size_t>(p)]);
}
