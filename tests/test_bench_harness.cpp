// The benchmark harness's statistics, call order and JSON schema (docs/bench.md); no timing
// assertions (speed figures belong in bench/).
#include <doctest/doctest.h>

#include <string>
#include <vector>

#include "../bench/harness.h"

namespace vb = vtsim::bench;

TEST_CASE("bench harness: percentiles, median and MAD") {
  const vb::Summary s = vb::summarize({5, 1, 3, 2, 4});
  CHECK(s.median == doctest::Approx(3));
  CHECK(s.min == 1);
  CHECK(s.max == 5);
  CHECK(s.p10 == doctest::Approx(1.4));  // 1 + 0.4 * (2 - 1)
  CHECK(s.p90 == doctest::Approx(4.6));
  CHECK(s.mad == doctest::Approx(1));    // deviations 2,2,0,1,1 -> median 1
  CHECK(s.samples == std::vector<double>{5, 1, 3, 2, 4});  // run order kept

  const vb::Summary even = vb::summarize({10, 20, 30, 40});
  CHECK(even.median == doctest::Approx(25));
  const vb::Summary one = vb::summarize({7});
  CHECK(one.median == 7);
  CHECK(one.p10 == 7);
  CHECK(one.mad == 0);
  CHECK(vb::summarize({}).median == 0);
}

TEST_CASE("bench harness: setup runs untimed before every repetition and the JSON follows the schema") {
  std::string a0 = "bench_test", a1 = "--reps", a2 = "4", a3 = "--warmup", a4 = "2";
  char* argv[] = {a0.data(), a1.data(), a2.data(), a3.data(), a4.data()};
  vb::Harness h("test", 5, argv);
  CHECK(h.options().reps == 4);
  CHECK(h.options().warmup == 2);
  int setups = 0, runs = 0, ref_setups = 0, ref_runs = 0;
  bool setup_before_run = true;
  int pending = 0;
  const vb::Result* r = h.compare(
      {.name = "case", .work = 1000, .params = {{"k", 1}}, .target_ratio = 1e9},
      {"ours", [&] { ++setups; ++pending; },
       [&] {
         setup_before_run &= pending == 1;
         pending = 0;
         ++runs;
         volatile int x = 0;
         for (int i = 0; i < 1000; ++i) x = x + i;
       }},
      {"ref", [&] { ++ref_setups; }, [&] { ++ref_runs; }});
  REQUIRE(r != nullptr);
  CHECK(setups == 6);  // 2 warm-up + 4 timed
  CHECK(runs == 6);
  CHECK(ref_setups == 6);
  CHECK(ref_runs == 6);
  CHECK(setup_before_run);
  CHECK(r->ours.samples.size() == 4);
  CHECK(r->ref.samples.size() == 4);
  CHECK(r->pair_ratios.size() == 4);
  CHECK(r->ratio > 0);
  CHECK_FALSE(r->meets_target);  // a 1e9x target cannot be met
  CHECK(r->ours.min <= r->ours.median);
  CHECK(r->ours.median <= r->ours.max);

  const vb::Result* alone =
      h.run({.name = "alone", .metric = vb::Metric::kMBPerS, .work = 1e6}, {"ours", {}, [] {}});
  REQUIRE(alone != nullptr);
  CHECK_FALSE(alone->reference.has_value());

  const nlohmann::json j = h.to_json();
  CHECK(j["schema"] == "vtsim-bench/1");
  CHECK(j["benchmark"] == "test");
  CHECK(j["reps"] == 4);
  for (const char* k : {"git", "time_utc", "quick", "warmup", "machine", "params", "results"})
    CHECK(j.contains(k));
  for (const char* k : {"hostname", "cpu", "logical_cores", "compiler", "optimized", "load_average_end"})
    CHECK(j["machine"].contains(k));
  REQUIRE(j["results"].size() == 2);
  const auto& e = j["results"][0];
  CHECK(e["name"] == "case");
  CHECK(e["unit"] == "ns/op");
  CHECK(e["better"] == "lower");
  CHECK(e["reps"] == 4);
  CHECK(e["params"]["k"] == 1);
  CHECK(e["reference"]["name"] == "ref");
  CHECK(e["samples"].size() == 4);
  CHECK(e["meets_target"] == false);
  for (const char* k : {"median", "min", "max", "p10", "p90", "mad", "ratio", "ratio_of_medians",
                        "pair_ratios", "target_ratio"})
    CHECK(e.contains(k));
  const auto& e2 = j["results"][1];
  CHECK(e2["unit"] == "MB/s");
  CHECK(e2["better"] == "higher");
  CHECK(e2["reference"].is_null());
  CHECK(e2["ratio"].is_null());
  CHECK(e2["meets_target"] == true);

  // --filter skips cases; the result list is unchanged.
  std::string f1 = "--filter", f2 = "nomatch";
  char* argv2[] = {a0.data(), f1.data(), f2.data()};
  vb::Harness h2("test2", 3, argv2);
  CHECK(h2.run({.name = "case"}, {"ours", {}, [] {}}) == nullptr);
  CHECK(h2.results().empty());
}

TEST_CASE("bench harness: add_measured() pairs externally timed repetitions, default repetitions") {
  std::string a0 = "bench_test";
  char* argv[] = {a0.data()};
  vb::Harness h("test", 1, argv, 3, 1);
  CHECK(h.options().reps == 3);  // the benchmark's own default
  const vb::Result* r = h.add_measured({.name = "replay", .metric = vb::Metric::kMsPerRep, .target_ratio = 2.5}, "divisor=8",
                                       {10, 20, 40}, "divisor=1", {40, 60, 80});
  REQUIRE(r != nullptr);
  CHECK(r->ours.median == 20);
  CHECK(r->ref.median == 60);
  CHECK(r->pair_ratios == std::vector<double>{4, 3, 2});  // ms: reference / ours
  CHECK(r->ratio == 3);
  CHECK(r->ratio_of_medians == 3);
  CHECK(r->meets_target);
  const auto j = h.to_json();
  CHECK(j["results"][0]["reference"]["name"] == "divisor=1");
  CHECK(j["results"][0]["ratio"] == 3.0);

  std::string q = "--quick";
  char* argv_q[] = {a0.data(), q.data()};
  CHECK(vb::Harness("test", 2, argv_q, 3, 1).options().reps == 1);
  CHECK(vb::Harness("test", 2, argv_q).options().reps == 7);
}

TEST_CASE("bench harness: quick mode holds no target a case did not declare valid there, and --strict exits 1 on a miss") {
  std::string a0 = "bench_test", q = "--quick", s = "--strict";
  char* argv_q[] = {a0.data(), q.data(), s.data()};
  vb::Harness h("test", 3, argv_q, 3, 1);
  // A full-run target on a quick run: not checked, null in the JSON.
  const vb::Result* r = h.add_measured({.name = "full_only", .metric = vb::Metric::kMsPerRep, .target_ratio = 1e9}, "a", {1},
                                       "b", {2});
  REQUIRE(r != nullptr);
  CHECK(r->meets_target);
  CHECK(r->spec.target_ratio == 0);
  // A target declared valid in quick mode is held.
  const vb::Result* held = h.add_measured(
      {.name = "quick_too", .metric = vb::Metric::kMsPerRep, .target_ratio = 1e9, .target_in_quick = true}, "a", {1}, "b", {2});
  REQUIRE(held != nullptr);
  CHECK_FALSE(held->meets_target);
  const auto j = h.to_json();
  CHECK(j["results"][0]["target_ratio"].is_null());
  CHECK(j["results"][1]["target_ratio"] == 1e9);
  CHECK(h.finish() == 1);  // --strict: the held target was missed

  char* argv_strict[] = {a0.data(), s.data()};
  vb::Harness h2("test", 2, argv_strict, 3, 1);
  CHECK(h2.finish() == 0);
  h2.missed_target();  // a benchmark's own accuracy check
  CHECK(h2.finish() == 1);
}
