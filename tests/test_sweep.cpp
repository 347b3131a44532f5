// Sweeps (docs/sweep.md): specs, view once / systems many against separate replays, shards and
// their merge, restart after a kill, determinism across thread counts, failures in a row.
#include <doctest/doctest.h>
#include <fmt/format.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/error.h"
#include "cache/policy/i_replacement.h"
#include "sim/run/frame_loop.h"
#include "sim/run/replay.h"
#include "sim/run/systems.h"
#include "sim/sweep/lockstep.h"
#include "sim/sweep/sweep.h"
#include "sim/sweep/sweep_table.h"
#include "sim/trace/trace_gen.h"
#include "sim/trace/trace_io.h"
#include "sim/view/scene.h"
#include "store_test_util.h"
#include "stream/throttle/i_throttle.h"
#include "test_util.h"

using namespace vtsim;

namespace {

void sweep_write(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

// The error message of loading `text` as a spec ("" when it loads).
std::string spec_error(const test::TempDir& d, const std::string& text) {
  sweep_write(d.file("spec.toml"), text);
  try {
    load_sweep_spec(d.file("spec.toml"));
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// A small sweep over two short generated traces: 2 × 2 grid, plus a second view group.
const char* kSpec = R"(name = "small"
set = ["view.divisor=16"]
generate = ["walk duration_s=3", "turn duration_s=3 event_s=1"]
[[configs]]
[[configs]]
"view.divisor" = 32
[grid]
"upload.tiles_per_frame" = [4, -1]
"disk.preset" = ["nvme", "hdd"]
)";

std::vector<std::string> joined_files(const std::string& dir) {
  return {test::slurp(dir + "/rows.jsonl"), test::slurp(dir + "/rows.csv"), test::slurp(dir + "/report.html")};
}

// The first 3 s of the town walk (tests/data), the lockstep's exactness cases' trace.
Trace short_town_walk() {
  Trace walk = load_trace(test::kData + "/town_walk.csv");
  while (!walk.poses.empty() && walk.poses.back().t_s > 3.0) walk.poses.pop_back();
  return walk;
}

// Every config's lockstep row, on 1..max_threads consumer threads, equals its replay alone (the
// replay's summary less its run's cost and build: sweep.json has the build). `alone` as
// run_replay gave them, in the same form.
void check_lockstep_exact(const std::vector<ReplayConfig>& cfgs, const std::vector<std::string>& alone, const Trace& walk,
                          const IScene& scene, std::initializer_list<int> thread_counts) {
  std::vector<const ReplayConfig*> ptrs;
  for (const auto& c : cfgs) ptrs.push_back(&c);
  for (int threads : thread_counts) {
    CAPTURE(threads);
    const std::vector<LockstepResult> rows = run_lockstep(ptrs, walk, scene, threads);
    REQUIRE(rows.size() == cfgs.size());
    for (std::size_t i = 0; i < cfgs.size(); ++i) {
      CAPTURE(cfgs[i].run.system);
      CAPTURE(cfgs[i].throttle.policy);
      CAPTURE(cfgs[i].ram.policy);
      REQUIRE(rows[i].ok);
      CHECK(rows[i].summary.dump() == alone[i]);
    }
  }
}

nlohmann::json alone_summary(const ReplayConfig& cfg, const Trace& walk, const IScene& scene) {
  ReplayResult r = run_replay(cfg, walk, scene);
  r.summary.erase("run");
  r.summary.erase("provenance");
  return std::move(r.summary);
}

}  // namespace

TEST_CASE("sweep: the lockstep rows equal each config's replay alone, every system × every throttle policy") {
  const Trace walk = short_town_walk();
  std::vector<ReplayConfig> cfgs;
  for (const auto& sys_entry : streaming_systems().entries())
    for (const auto& policy_entry : throttle_policies().entries()) {
      const std::string system(sys_entry.name), policy(policy_entry.name);
      std::vector<std::string> sets = {"scene.kind=town", "view.render_threads=0", "run.system=" + system,
                                       "throttle.policy=" + policy, "upload.tiles_per_frame=6"};
      if (system == "vt") sets.push_back("vt.pool_pages=96");  // oversubscribed: the VT policies engage
      cfgs.push_back(load_replay_config("", sets));
    }
  REQUIRE(cfgs.size() >= 10);
  const auto scene = make_scene_from_config(cfgs[0]);
  std::vector<std::string> alone;
  for (const auto& c : cfgs) alone.push_back(alone_summary(c, walk, *scene).dump());
  check_lockstep_exact(cfgs, alone, walk, *scene, {1, 2, 3});  // 2: one leader and the follower; 3: two leaders
}

TEST_CASE("sweep: the lockstep rows equal each config's replay alone, every system × every replacement policy") {
  const Trace walk = short_town_walk();
  std::vector<ReplayConfig> cfgs;
  for (const auto& sys_entry : streaming_systems().entries())
    for (const auto& policy_entry : replacement_policies().entries()) {
      const std::string system(sys_entry.name), policy(policy_entry.name);
      // RAM and the VT pool small enough that both levels evict, so the policy decides.
      std::vector<std::string> sets = {"scene.kind=town", "view.render_threads=0", "run.system=" + system,
                                       "ram.policy=" + policy, "ram.capacity_MiB=2", "upload.tiles_per_frame=6"};
      if (system == "vt") sets.insert(sets.end(), {"vt.pool_pages=96", "vt.pool_policy=" + policy});
      cfgs.push_back(load_replay_config("", sets));
    }
  REQUIRE(cfgs.size() >= 10);
  const auto scene = make_scene_from_config(cfgs[0]);
  std::vector<std::string> alone;
  for (const auto& c : cfgs) {
    const nlohmann::json s = alone_summary(c, walk, *scene);
    CAPTURE(c.run.system);
    CHECK(s["cache"]["ram_evictions"].get<std::uint64_t>() > 0);
    if (c.run.system == "vt") CHECK(s["vt"]["pool"]["evictions"].get<std::uint64_t>() > 0);
    alone.push_back(s.dump());
  }
  check_lockstep_exact(cfgs, alone, walk, *scene, {1, 2});
}

TEST_CASE("sweep: runs in the same state share their pop-in and end exactly as alone (clipmap, terrain)") {
  const Trace walk = short_town_walk();
  for (const char* system : {"clipmap", "terrain"}) {
    CAPTURE(system);
    // RAM size and disk differ, the clipmaps mostly not: the second run finds the first's entries.
    std::vector<ReplayConfig> cfgs;
    for (const char* ram : {"ram.capacity_MiB=8", "ram.capacity_MiB=256"})
      cfgs.push_back(load_replay_config("", {"view.render_threads=0", std::string("run.system=") + system, ram, "upload.tiles_per_frame=4"}));
    const auto scene = make_scene_from_config(cfgs[0]);
    const FramePlan plan = plan_frames(cfgs[0], walk);
    const ReplayEnv env;
    SystemRun r0(cfgs[0], plan, *scene, env), r1(cfgs[1], plan, *scene, env);
    ViewStream view(cfgs[0], plan, *scene, r0.block_shift(), false, 0);
    PopinShare share;
    for (int f = 0; f < plan.frames; ++f) {
      const FrameView& v = view.frame(f, false);
      share.begin_frame(v.popin);
      for (SystemRun* r : {&r0, &r1}) {
        r->begin_frame(f, plan.target(f));
        r->step(v, &share);
      }
    }
    CHECK(r1.popin_share_counts().levels_shared > static_cast<std::uint64_t>(plan.frames) / 2);
    CHECK(r0.popin_share_counts().levels_resolved > 0);
    CHECK(r0.popin_share_counts().levels_shared == 0);  // the first run of a frame finds nothing
    CHECK(r1.popin_share_counts().frames_shared > 0);
    for (int i = 0; i < 2; ++i) {
      ReplayResult shared = (i == 0 ? r0 : r1).summarize(RunCost{});
      ReplayResult alone = run_replay(cfgs[static_cast<std::size_t>(i)], walk, *scene);
      for (auto* j : {&shared.summary, &alone.summary}) {
        j->erase("run");
        j->erase("provenance");
      }
      CHECK(shared.summary.dump() == alone.summary.dump());
    }
  }
}

TEST_CASE("sweep: configs with another view are refused by the lockstep runner, and view_key ignores render_threads") {
  const ReplayConfig a = load_replay_config("", {});
  const ReplayConfig b = load_replay_config("", {"view.divisor=4"});
  const ReplayConfig c = load_replay_config("", {"view.render_threads=3", "upload.tiles_per_frame=2", "run.system=vt"});
  CHECK(view_key(a) != view_key(b));
  CHECK(view_key(a) == view_key(c));
  const auto scene = make_scene_from_config(a);
  CHECK_THROWS_AS(run_lockstep({&a, &b}, generate_trace(default_gen_params("walk")), *scene, 1), std::invalid_argument);
}

TEST_CASE("sweep: a spec expands explicit configs × grid, first axis slowest, in the file's order") {
  test::TempDir d;
  sweep_write(d.file("spec.toml"), kSpec);
  const SweepSpec s = load_sweep_spec(d.file("spec.toml"));
  CHECK(s.name == "small");
  REQUIRE(s.traces.size() == 2);
  CHECK(s.traces[0].generated);
  REQUIRE(s.points.size() == 8);
  REQUIRE(s.grid.size() == 2);
  CHECK(s.grid[0].key == "upload.tiles_per_frame");  // the file's order, not toml++'s sorted one
  CHECK(s.points[0].cfg.upload.tiles_per_frame == 4);
  CHECK(s.points[0].cfg.disk.preset == "nvme");
  CHECK(s.points[1].cfg.disk.preset == "hdd");
  CHECK(s.points[2].cfg.upload.tiles_per_frame == -1);
  CHECK(s.points[0].cfg.view.divisor == 16);
  CHECK(s.points[4].cfg.view.divisor == 32);
  CHECK(s.points[4].values.front() == std::pair<std::string, std::string>{"view.divisor", "32"});
  CHECK(s.axis_keys == std::vector<std::string>{"upload.tiles_per_frame", "disk.preset", "view.divisor"});
  CHECK(s.metrics == default_sweep_metrics());
}

TEST_CASE("sweep: spec errors name file:line and the key, before anything runs") {
  test::TempDir d;
  const std::string f = d.file("spec.toml");
  CHECK(test::contains(spec_error(d, "generate = [\"walk\"]\n[grid]\n\"upload.tiles_per_frme\" = [1, 2]\n"),
                       f + ":3: unknown config key 'upload.tiles_per_frme' (did you mean 'upload.tiles_per_frame'?)"));
  CHECK(test::contains(spec_error(d, "generate = [\"walk\"]\n[grid]\n\"upload.tiles_per_frame\" = []\n"),
                       f + ":3: grid key 'upload.tiles_per_frame': an empty axis"));
  CHECK(test::contains(spec_error(d, "generate = [\"walk\"]\n[grid]\n\"view.divisor\" = [4, 0]\n"), f + ":3: field 'view.divisor'"));
  CHECK(test::contains(spec_error(d, "generate = [\"walk\"]\ntrace = [\"a.csv\"]\n"), f + ":2: unknown spec key 'trace'"));
  CHECK(test::contains(spec_error(d, "traces = [\"nothing-*.csv\"]\n"), "matches no file"));
  CHECK(test::contains(spec_error(d, "generate = [\"walk speed=3\"]\n"), f + ":1: generate: unknown generator key 'speed'"));
  CHECK(test::contains(spec_error(d, "generate = [\"crawl\"]\n"), "unknown trace kind 'crawl'"));
  CHECK(test::contains(spec_error(d, "name = \"x\"\n"), "no traces"));
  CHECK(test::contains(spec_error(d, "generate = [\"walk\"]\n[grid]\n\"disk.preset\" = [\"hdd\", \"floppy\"]\n"),
                       "unknown disk preset 'floppy'"));
  // Cross-field checks name the point and its values.
  CHECK(test::contains(spec_error(d, "generate = [\"walk\"]\n[[configs]]\n\"clipmap.clipsize\" = 100\n"),
                       f + ": config point 0 (clipmap.clipsize = 100): config: field 'clipmap.clipsize'"));
  // A key or value given twice, or in both [[configs]] and [grid], would run a config twice or
  // silently drop one of the values.
  CHECK(test::contains(spec_error(d, "generate = [\"walk\"]\n[grid]\n\"upload.tiles_per_frame\" = [4, 8, 4]\n"),
                       f + ":3: grid key 'upload.tiles_per_frame': the value 4 twice"));
  CHECK(test::contains(spec_error(d, "generate = [\"walk\"]\n[grid]\n\"upload.tiles_per_frame\" = [4]\n[grid.upload]\ntiles_per_frame = [8]\n"),
                       f + ":5: grid key 'upload.tiles_per_frame': an axis already (line 3)"));
  CHECK(test::contains(spec_error(d, "generate = [\"walk\"]\n[grid]\n\"upload.tiles_per_frame\" = [4]\n[[configs]]\n\"upload.tiles_per_frame\" = 8\n"),
                       f + ":5: [[configs]]: key 'upload.tiles_per_frame' is also a [grid] axis (line 3)"));
  CHECK(test::contains(spec_error(d, "generate = [\"walk\"]\nmetrics = [\"latency_ms.p99\", \"latency_ms.p99\"]\n"),
                       f + ":2: metrics: 'latency_ms.p99' twice"));
  // The base config's errors say where the spec named it.
  CHECK(test::contains(spec_error(d, "generate = [\"walk\"]\nset = [\"upload.tiles_per_frame=abc\"]\n"),
                       f + ":2: key 'set': 'upload.tiles_per_frame=abc': "));
  CHECK(test::contains(spec_error(d, "generate = [\"walk\"]\nconfig = \"no-base.toml\"\n"), f + ":2: key 'config': "));
  sweep_write(d.file("base.toml"), "[upload]\ntiles_per_frame = \"x\"\n");
  CHECK(test::contains(spec_error(d, "generate = [\"walk\"]\nconfig = \"base.toml\"\n"),
                       f + ":2: key 'config': " + d.file("base.toml") + ":2: field 'upload.tiles_per_frame'"));
  CHECK(spec_error(d, "generate = [\"walk\"]\n") == "");
}

TEST_CASE("sweep: a metric or tune constraint that no summary holds is refused before anything is written") {
  test::TempDir d;
  const auto refused = [&](const std::string& text) {
    sweep_write(d.file("spec.toml"), text);
    const SweepSpec spec = load_sweep_spec(d.file("spec.toml"));
    SweepOptions o;
    o.out_dir = d.file("out");
    std::string err;
    try {
      run_sweep(spec, o);
    } catch (const InputError& e) {
      err = e.what();
    }
    CHECK_FALSE(std::filesystem::exists(o.out_dir));
    std::filesystem::remove_all(o.out_dir);
    return err;
  };
  const std::string f = d.file("spec.toml");
  const std::string g = "generate = [\"walk duration_s=1\"]\n";
  CHECK(test::contains(refused(g + "metrics = [\"popin.blurry_fraction_p95\", \"popin.nosuch\"]\n"),
                       f + ":2: metrics: 'popin.nosuch' is not a value of a replay summary: popin has no key 'nosuch' (keys: "));
  CHECK(test::contains(refused(g + "metrics = [\"latency_ms\"]\n"), "latency_ms is a section, not a value"));
  // A point whose probe fails (its scene does not load) is followed by the next of its system.
  CHECK(test::contains(refused(g + "metrics = [\"popin.nosuch\"]\n[[configs]]\n\"scene.kind\" = \"heightfield\"\n"
                                   "\"scene.file\" = \"no-such-height.png\"\n[[configs]]\n"),
                       "popin has no key 'nosuch'"));
  CHECK(test::contains(refused(g + "metrics = [\"bandwidth.per_level.first.disk_read_MBps\"]\n"),
                       "bandwidth.per_level is a list: give an element's number"));
  CHECK(test::contains(refused(g + "[grid]\n\"upload.tiles_per_frame\" = [4, 8]\n[tune]\nconstraints = [\n  \"latency_ms.p99 <= 200\",\n"
                                   "  \"popin.blurry_p99 <= 0.02\"]\n"),
                       f + ":5: tune.constraints: 'popin.blurry_p99' is not a value"));
  // Paths that hold in some summaries: an element of a list by number (any: lists differ in
  // length), a section only runs that produce have, the system's own section, the defaults.
  sweep_write(d.file("spec.toml"), g + "metrics = [\"bandwidth.per_level.0.disk_read_MBps\", \"bandwidth.per_level.99.disk_read_MBps\", "
                                       "\"produce.requests\", \"vt.pool.evictions\", \"clipmap.levels\"]\n"
                                       "[grid]\n\"run.system\" = [\"clipmap\", \"vt\"]\n");
  const SweepSpec ok = load_sweep_spec(d.file("spec.toml"));
  CHECK_NOTHROW(check_sweep_metrics(ok, load_sweep_traces(ok)));
  sweep_write(d.file("spec.toml"), g + "[grid]\n\"run.system\" = [\"clipmap\", \"vt\", \"terrain\"]\n");
  const SweepSpec defaults = load_sweep_spec(d.file("spec.toml"));
  CHECK_NOTHROW(check_sweep_metrics(defaults, load_sweep_traces(defaults)));
}

TEST_CASE("sweep: shards merged give exactly the unsharded outputs, and --jobs changes nothing") {
  test::TempDir d;
  sweep_write(d.file("spec.toml"), kSpec);
  const SweepSpec spec = load_sweep_spec(d.file("spec.toml"));
  SweepOptions one;
  one.out_dir = d.file("one");
  one.jobs = 1;
  const SweepRunStats st = run_sweep(spec, one);
  CHECK(st.rows == 16);
  CHECK(st.rows_failed == 0);
  CHECK(st.views_rendered == 4);  // 2 traces × 2 view groups: each view rendered once
  SweepOptions many = one;
  many.out_dir = d.file("many");
  many.jobs = 3;
  run_sweep(spec, many);
  CHECK(joined_files(one.out_dir) == joined_files(many.out_dir));
  std::vector<std::string> shards;
  for (int i = 0; i < 3; ++i) {
    SweepOptions o = one;
    o.out_dir = d.file("shard" + std::to_string(i));
    o.shard = {i, 3};
    run_sweep(spec, o);
    CHECK_FALSE(std::filesystem::exists(o.out_dir + "/rows.jsonl"));  // a shard is joined by merge
    shards.push_back(o.out_dir);
  }
  merge_sweep(shards, d.file("merged"));
  CHECK(joined_files(one.out_dir) == joined_files(d.file("merged")));
  // The rows are what `vtsim replay` gives: one row checked against a replay alone.
  const std::string first = test::slurp(one.out_dir + "/rows.jsonl").substr(0, test::slurp(one.out_dir + "/rows.jsonl").find('\n'));
  const nlohmann::json row = nlohmann::json::parse(first);
  ReplayResult alone = run_replay(spec.points[0].cfg, load_sweep_trace(spec.traces[0]), *make_scene_from_config(spec.points[0].cfg));
  alone.summary.erase("run");
  alone.summary.erase("provenance");
  CHECK(row["summary"].dump() == alone.summary.dump());
  CHECK(row["config"] == 0);
  CHECK(row["trace"] == 0);
  // The row keeps the effective config; the build is recorded once, in sweep.json.
  CHECK(row["summary"]["config"]["disk.preset"] == spec.points[0].cfg.disk.preset);
  CHECK_FALSE(row["summary"].contains("provenance"));
  const nlohmann::json sweep_json = nlohmann::json::parse(test::slurp(one.out_dir + "/sweep.json"));
  CHECK(sweep_json["provenance"]["vtsim_version"] == VTSIM_VERSION);
  CHECK(sweep_json["provenance"]["vtsim_commit"].is_string());

  // Merge refuses a missing shard, a shard twice, a shard of another spec, an incomplete one.
  CHECK_THROWS_WITH_AS(merge_sweep({shards[0], shards[2]}, d.file("m2")), doctest::Contains("shard 1/3 is missing"), InputError);
  CHECK_THROWS_WITH_AS(merge_sweep({shards[0], shards[1], shards[1]}, d.file("m3")), doctest::Contains("again"), InputError);
  sweep_write(d.file("spec2.toml"), std::string(kSpec) + "\"ram.capacity_MiB\" = [64]\n");
  SweepOptions other = one;
  other.out_dir = d.file("other");
  other.shard = {2, 3};
  run_sweep(load_sweep_spec(d.file("spec2.toml")), other);
  CHECK_THROWS_WITH_AS(merge_sweep({shards[0], shards[1], other.out_dir}, d.file("m4")), doctest::Contains("another spec"),
                       InputError);
  std::string sj = test::slurp(shards[1] + "/shard.json");
  sj.replace(sj.find("\"complete\": true"), 16, "\"complete\": false");
  sweep_write(shards[1] + "/shard.json", sj);
  CHECK_THROWS_WITH_AS(merge_sweep(shards, d.file("m5")), doctest::Contains("incomplete"), InputError);
  // A complete shard whose parts/ was tampered with: the error names that shard's directory.
  sj.replace(sj.find("\"complete\": false"), 17, "\"complete\": true");
  sweep_write(shards[1] + "/shard.json", sj);
  std::vector<std::filesystem::path> parts1;
  for (const auto& e : std::filesystem::directory_iterator(shards[1] + "/parts")) parts1.push_back(e.path());
  REQUIRE_FALSE(parts1.empty());
  std::filesystem::copy_file(parts1[0], shards[1] + "/parts/copy.jsonl");
  CHECK_THROWS_WITH_AS(merge_sweep(shards, d.file("m6")), doctest::Contains((shards[1] + ": work items ").c_str()), InputError);
  CHECK_THROWS_WITH_AS(merge_sweep(shards, d.file("m6")), doctest::Contains("are in two parts"), InputError);
  std::filesystem::remove(shards[1] + "/parts/copy.jsonl");
  std::filesystem::remove(parts1[0]);
  CHECK_THROWS_WITH_AS(merge_sweep(shards, d.file("m7")), doctest::Contains((shards[1] + ": work items ").c_str()), InputError);
  CHECK_THROWS_WITH_AS(merge_sweep(shards, d.file("m7")), doctest::Contains("are missing from parts/"), InputError);
  CHECK_FALSE(std::filesystem::exists(d.file("m6")));
  CHECK_FALSE(std::filesystem::exists(d.file("m7")));
  // A shard directory of one spec is not reused for another.
  CHECK_THROWS_WITH_AS(run_sweep(load_sweep_spec(d.file("spec2.toml")), one), doctest::Contains("another spec"), InputError);
}

TEST_CASE("sweep: a killed sweep restarted on the same output redoes only the unfinished tasks") {
  test::TempDir d;
  sweep_write(d.file("spec.toml"), kSpec);
  const SweepSpec spec = load_sweep_spec(d.file("spec.toml"));
  SweepOptions o;
  o.out_dir = d.file("out");
  o.jobs = 2;
  run_sweep(spec, o);
  const std::vector<std::string> before = joined_files(o.out_dir);
  // What a kill leaves: some parts done, one in flight (its hidden temporary, core/atomic_file.h),
  // no joined outputs.
  std::vector<std::filesystem::path> parts;
  for (const auto& f : std::filesystem::directory_iterator(o.out_dir + "/parts")) parts.push_back(f.path());
  std::sort(parts.begin(), parts.end());
  REQUIRE(parts.size() == 4);
  const std::string kept = test::slurp(parts[0].string());
  const std::string in_flight = (parts[1].parent_path() / ("." + parts[1].filename().string() + ".tmp-a1B2c3")).string();
  std::filesystem::rename(parts[1], in_flight);
  std::filesystem::remove(parts[3]);
  for (const char* f : {"/rows.jsonl", "/rows.csv", "/report.html"}) std::filesystem::remove(o.out_dir + f);
  const SweepRunStats st = run_sweep(spec, o);
  CHECK(st.rows_skipped == 8);  // parts 0 and 2: 4 rows each
  CHECK(st.rows - st.rows_skipped == 8);
  CHECK(test::slurp(parts[0].string()) == kept);
  CHECK_FALSE(std::filesystem::exists(in_flight));
  CHECK(joined_files(o.out_dir) == before);
}

TEST_CASE("sweep CLI: a sweep killed with SIGKILL and started again on its output loses and repeats nothing") {
  test::TempDir d;
  // Four tasks (two traces × two views) of ~0.3 s of CPU each in Release (~4x that under the
  // sanitizers), one at a time: the poller (every 10 ms) has the other three's time to see the
  // first part and kill.
  sweep_write(d.file("spec.toml"), "set = [\"run.system=vt\", \"scene.kind=town\", \"view.render_threads=0\"]\n"
                                  "generate = [\"walk duration_s=20 start_m=30,8\", \"walk duration_s=20 start_m=40,8\"]\n"
                                  "[grid]\n\"vt.pool_pages\" = [128, 512]\n\"view.divisor\" = [16, 32]\n");
  const std::string spec = d.file("spec.toml"), ref = d.file("ref"), out = d.file("out");
  test::CliRun r = test::run_vtsim_capture("sweep " + spec + " -o " + ref + " -q --jobs 1", d.file("err"));
  REQUIRE(r.code == 0);
  // Killed as soon as its first task's part is on disk: the shell prints the status `wait` saw.
  r = test::run_capture("sh -c '" + std::string(VTSIM_CLI) + " sweep " + spec + " -o " + out + " -q --jobs 1 & p=$!; i=0; "
                        "while [ $i -lt 12000 ] && ! ls " + out + "/parts/*.jsonl >/dev/null 2>&1; do sleep 0.01; i=$((i+1)); done; "
                        "kill -9 $p; wait $p; echo $?' 2>" + d.file("err"), d.file("err"));
  REQUIRE(r.out == "137\n");  // 128 + SIGKILL: it was killed, not finished
  CHECK_FALSE(std::filesystem::exists(out + "/rows.jsonl"));
  std::size_t parts = 0;
  for (const auto& e : std::filesystem::directory_iterator(out + "/parts")) parts += e.path().extension() == ".jsonl";
  CHECK(parts >= 1);
  CHECK(parts < 4);
  // Started again: it finishes the other tasks (progress on stderr), and the outputs are the
  // uninterrupted sweep's, byte for byte.
  r = test::run_vtsim_capture("sweep " + spec + " -o " + out + " --jobs 1 --progress", d.file("err"));
  CHECK(r.code == 0);
  CHECK(test::contains(r.out, fmt::format("8 rows ({} run now, {} already done, 0 failed)", 8 - 2 * parts, 2 * parts)));
  CHECK(test::contains(r.err, "rows done), "));
  CHECK(joined_files(out) == joined_files(ref));
}

TEST_CASE("sweep: a row whose replay fails says why in its row, and the others run") {
  test::TempDir d;
  sweep_write(d.file("spec.toml"), "generate = [\"walk duration_s=1\"]\n[[configs]]\n[[configs]]\n"
                                  "\"scene.kind\" = \"heightfield\"\n\"scene.file\" = \"no-such-height.png\"\n");
  const SweepSpec spec = load_sweep_spec(d.file("spec.toml"));
  SweepOptions o;
  o.out_dir = d.file("out");
  const SweepRunStats st = run_sweep(spec, o);
  CHECK(st.rows == 2);
  CHECK(st.rows_failed == 1);
  const std::string rows = test::slurp(o.out_dir + "/rows.jsonl");
  CHECK(test::contains(rows, "\"status\":\"ok\""));
  CHECK(test::contains(rows, "\"status\":\"error\""));
  CHECK(test::contains(rows, "no-such-height.png"));
  CHECK(test::contains(test::slurp(o.out_dir + "/rows.csv"), ",error,"));
}

TEST_CASE("sweep: shards by I/N or from Slurm's array variables") {
  CHECK(parse_shard("0/4", "--shard").index == 0);
  CHECK(parse_shard("3/4", "--shard").count == 4);
  for (const char* bad : {"4/4", "-1/4", "1/0", "1", "a/b", "1/4x", "/4"}) {
    CAPTURE(bad);
    CHECK_THROWS_AS(parse_shard(bad, "--shard"), InputError);
  }
  ::setenv("SLURM_ARRAY_TASK_ID", "7", 1);
  ::setenv("SLURM_ARRAY_TASK_MIN", "5", 1);
  ::setenv("SLURM_ARRAY_TASK_COUNT", "4", 1);
  const SweepShard s = parse_shard("slurm", "--shard");
  CHECK(s.index == 2);
  CHECK(s.count == 4);
  ::setenv("SLURM_ARRAY_TASK_ID", "9", 1);
  CHECK_THROWS_AS(parse_shard("slurm", "--shard"), InputError);
  ::unsetenv("SLURM_ARRAY_TASK_ID");
  ::unsetenv("SLURM_ARRAY_TASK_MIN");
  ::unsetenv("SLURM_ARRAY_TASK_COUNT");
  CHECK_THROWS_WITH_AS(parse_shard("slurm", "--shard"), doctest::Contains("SLURM_ARRAY_TASK_ID"), InputError);
}

TEST_CASE("sweep: generator lines are a generated trace's name") {
  const TraceGenParams p = parse_gen_line("turn duration_s=30 start_m=30,8 turn_deg=-90 image=640x360", "g");
  CHECK(p.kind == "turn");
  CHECK(p.duration_s == 30.0);
  CHECK(p.start_m == glm::dvec2(30.0, 8.0));
  CHECK(p.turn_deg == -90.0);
  CHECK(p.image_width == 640);
  const Trace t = generate_trace(default_gen_params("orbit"));
  const Trace again = generate_trace(parse_gen_line(t.name, "g"));
  CHECK(again.name == t.name);
  CHECK(again.poses.size() == t.poses.size());
  CHECK_THROWS_AS(parse_gen_line("walk duration_s=abc", "g"), InputError);
  CHECK_THROWS_AS(parse_gen_line("walk start_m=1", "g"), InputError);
  CHECK_THROWS_AS(parse_gen_line("", "g"), InputError);
}

TEST_CASE("sweep: the example specs in docs/examples load") {
  for (const char* f : {"sweep_vt_town.toml", "tune_vt_town.toml"}) {
    CAPTURE(f);
    const SweepSpec s = load_sweep_spec(std::string(VTSIM_SOURCE_DIR) + "/docs/examples/" + f);
    CHECK(s.points.size() == (s.tune.present ? 36u : 16u));
    CHECK(load_sweep_traces(s).size() == 2);
  }
}

TEST_CASE("sweep CLI: exit 2 for a bad spec or merge, 1 when a row failed, 0 otherwise") {
  test::TempDir d;
  sweep_write(d.file("bad.toml"), "generate = [\"walk\"]\n[grid]\n\"view.divisr\" = [4]\n");
  test::CliRun r = test::run_vtsim_capture("sweep " + d.file("bad.toml") + " -o " + d.file("o1"), d.file("err"));
  CHECK(r.code == 2);
  CHECK(test::contains(r.err, "bad.toml:3: unknown config key 'view.divisr' (did you mean 'view.divisor'?)"));
  CHECK_FALSE(std::filesystem::exists(d.file("o1")));  // nothing written
  sweep_write(d.file("fail.toml"), "generate = [\"walk duration_s=1\"]\n[[configs]]\n[[configs]]\n\"scene.kind\" = \"heightfield\"\n"
                                  "\"scene.file\" = \"missing.png\"\n");
  r = test::run_vtsim_capture("sweep " + d.file("fail.toml") + " -o " + d.file("o2") + " -q", d.file("err"));
  CHECK(r.code == 1);
  CHECK(std::filesystem::exists(d.file("o2") + "/rows.csv"));
  sweep_write(d.file("ok.toml"), "generate = [\"walk duration_s=1\"]\n");
  r = test::run_vtsim_capture("sweep " + d.file("ok.toml") + " -o " + d.file("o3"), d.file("err"));
  CHECK(r.code == 0);
  CHECK(test::contains(r.out, "1 rows (1 run now, 0 already done, 0 failed)"));
  r = test::run_vtsim_capture("sweep merge -o " + d.file("m") + " " + d.file("o3") + " " + d.file("nothing"), d.file("err"));
  CHECK(r.code == 2);
  CHECK(test::contains(r.err, "not a sweep shard directory"));
  r = test::run_vtsim_capture("sweep " + d.file("ok.toml") + " -o " + d.file("o4") + " --shard 4/4", d.file("err"));
  CHECK(r.code == 2);
  CHECK(test::contains(r.err, "--shard: '4/4' is not I/N"));
}

TEST_CASE("sweep: the spec hash is the traces' content, not the paths they are read from") {
  test::TempDir d;
  std::filesystem::create_directories(d.file("sub"));
  std::filesystem::copy_file(std::string(VTSIM_SOURCE_DIR) + "/traces/walk.csv", d.file("walk.csv"));
  sweep_write(d.file("a.toml"), "traces = [\"walk.csv\"]\n");
  sweep_write(d.file("sub/b.toml"), "traces = [\"" + d.file("walk.csv") + "\"]\n");
  const SweepSpec a = load_sweep_spec(d.file("a.toml")), b = load_sweep_spec(d.file("sub/b.toml"));
  CHECK(sweep_spec_hash(a, load_sweep_traces(a)) == sweep_spec_hash(b, load_sweep_traces(b)));
  sweep_write(d.file("c.toml"), "traces = [\"walk.csv\"]\n[grid]\n\"upload.tiles_per_frame\" = [4]\n");
  const SweepSpec c = load_sweep_spec(d.file("c.toml"));
  CHECK(sweep_spec_hash(a, load_sweep_traces(a)) != sweep_spec_hash(c, load_sweep_traces(c)));
}

TEST_CASE("sweep table: one pivot table per metric, cells from the one row with those values, errors name the flag") {
  test::TempDir d;
  sweep_write(d.file("spec.toml"), kSpec);
  SweepOptions o;
  o.out_dir = d.file("o");
  o.jobs = 1;
  run_sweep(load_sweep_spec(d.file("spec.toml")), o);
  const SweepOutputs out = load_sweep_outputs(d.file("o"));
  REQUIRE(out.rows.size() == 16);  // 2 configs × (2 × 2) grid × 2 traces
  SweepTableSpec t;
  t.rows = {"trace", "view.divisor", "disk.preset"};
  t.col = "upload.tiles_per_frame";
  t.metrics = {"trace.frames", "popin.blurry_fraction_mean"};
  const std::string md = sweep_table(out, t);
  CHECK(test::contains(md, "**trace.frames**"));
  CHECK(test::contains(md, "| trace | view.divisor | disk.preset | upload.tiles_per_frame = 4 | upload.tiles_per_frame = -1 |"));
  // Every cell of the first table is its row's frame count, read straight from rows.jsonl.
  for (const auto& r : out.rows) {
    const std::string line = "| " + out.meta["traces"][r["trace"].get<std::size_t>()]["name"].get<std::string>() + " | ";
    CHECK(test::contains(md, line));
  }
  t.csv = true;
  const std::string csv = sweep_table(out, t);
  std::size_t lines = 0;
  for (char c : csv) lines += c == '\n';
  CHECK(lines == 1 + 2 * out.rows.size());  // header + one line per (metric, row)
  CHECK(csv.rfind("metric,trace,view.divisor,disk.preset,upload.tiles_per_frame,value\n", 0) == 0);
  CHECK(test::contains(csv, "," + out.rows[0]["summary"]["trace"]["frames"].dump() + "\n"));

  SweepTableSpec bad = t;
  bad.rows = {"trace"};
  CHECK_THROWS_WITH_AS(sweep_table(out, bad), doctest::Contains("to --rows or --col"), InputError);
  bad.rows = {"trace", "disk.prest"};
  CHECK_THROWS_WITH_AS(sweep_table(out, bad), doctest::Contains("did you mean 'disk.preset'"), InputError);
  bad = t;
  bad.metrics = {"popin.nothing_here"};
  CHECK_THROWS_WITH_AS(sweep_table(out, bad), doctest::Contains("--metric"), InputError);
  CHECK_THROWS_WITH_AS(load_sweep_outputs(d.file("nothing")), doctest::Contains("no sweep.json"), InputError);
  // Outputs not as vtsim writes them: errors naming the file, never a crash.
  std::filesystem::create_directories(d.file("bad"));
  sweep_write(d.file("bad/sweep.json"), R"({"meta": {"traces": [{"name": 3}]}})");
  sweep_write(d.file("bad/rows.jsonl"), "");
  CHECK_THROWS_WITH_AS(load_sweep_outputs(d.file("bad")), doctest::Contains("meta.traces"), InputError);
  sweep_write(d.file("bad/sweep.json"), R"({"meta": {"traces": [{"name": "t"}], "axis_keys": []}})");
  sweep_write(d.file("bad/rows.jsonl"), R"({"trace": 0, "config": 0, "values": {}, "status": "ok"})" "\n");
  CHECK_THROWS_WITH_AS(load_sweep_outputs(d.file("bad")), doctest::Contains("rows.jsonl:1: an ok row without a summary"), InputError);
  sweep_write(d.file("bad/rows.jsonl"), R"({"trace": 0, "config": 0, "values": {}, "status": 7})" "\n");
  CHECK_THROWS_WITH_AS(load_sweep_outputs(d.file("bad")), doctest::Contains("status is not a string"), InputError);
}
