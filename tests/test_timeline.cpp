// The tile timeline (`vtsim replay --timeline`, sim/run/timeline.h): the Trace Event JSON parses,
// its events count what the summary counts, it is byte-identical run to run in the simulated
// clock, --timeline-frames limits it, and a timeline over its bound is refused before the run.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <utility>
#include <nlohmann/json.hpp>
#include <set>

#include "core/error.h"
#include "sim/report/waterfall.h"
#include "sim/run/replay.h"
#include "sim/run/timeline.h"
#include "sim/trace/trace_gen.h"
#include "sim/trace/trace_io.h"
#include "test_util.h"

using namespace vtsim;

namespace {

// A fast walk (8 m/s, 3 s) over the default plane: windows move, tiles are cancelled and evicted.
Trace timeline_walk() {
  TraceGenParams g = default_gen_params("walk");
  g.duration_s = 3.0;
  g.speed_mps = 8.0;
  g.image_width = 640;
  g.image_height = 360;
  return generate_trace(g);
}

struct TimelineRun {
  ReplayResult result;
  std::string json;
};

TimelineRun timeline_run(const std::vector<std::string>& sets, TimelineOptions opt = {}) {
  const ReplayConfig cfg = load_replay_config("", sets);
  const auto scene = make_scene_from_config(cfg);
  TimelineRecorder tl(opt);
  ReplayEnv env;
  env.timeline = &tl;
  TimelineRun r;
  r.result = run_replay(cfg, timeline_walk(), *scene, env);
  r.json = tl.json();
  return r;
}

struct EventCounts {
  std::map<std::string, std::uint64_t> by_name;  // X and i events by name
  std::uint64_t decoded_bytes = 0;
  std::set<std::uint64_t> flow_s, flow_f;
  std::set<int> request_frames;
  std::uint64_t frames = 0;
};

EventCounts count_events(const nlohmann::json& j) {
  EventCounts c;
  REQUIRE(j.contains("traceEvents"));
  for (const auto& e : j["traceEvents"]) {
    const std::string ph = e["ph"];
    const std::string name = e["name"];
    if (ph == "M") continue;
    REQUIRE(e.contains("ts"));
    REQUIRE(e["ts"].is_number());
    if (ph == "s") c.flow_s.insert(e["id"].get<std::uint64_t>());
    if (ph == "f") {
      CHECK(e["bp"] == "e");
      c.flow_f.insert(e["id"].get<std::uint64_t>());
    }
    if (ph != "X" && ph != "i") continue;
    if (ph == "X") CHECK(e["dur"].get<double>() >= 0.0);
    ++c.by_name[name];
    if (name == "decode") c.decoded_bytes += e["args"]["bytes"].get<std::uint64_t>();
    if (name == "request") c.request_frames.insert(e["args"]["frame"].get<int>());
    if (name == "frame") ++c.frames;
  }
  return c;
}

void check_counts_match(const TimelineRun& r) {
  const nlohmann::json j = nlohmann::json::parse(r.json);
  EventCounts c = count_events(j);
  const auto& s = r.result.summary;
  CHECK(c.frames == s["trace"]["frames"].get<std::uint64_t>());
  CHECK(c.by_name["request"] == s["cache"]["requests"].get<std::uint64_t>());
  CHECK(c.by_name["read"] == s["bandwidth"]["disk_reads"].get<std::uint64_t>());
  CHECK(c.decoded_bytes == s["bandwidth"]["decoded_bytes"].get<std::uint64_t>());
  CHECK(c.by_name["upload"] == s["bandwidth"]["uploads"].get<std::uint64_t>());
  CHECK(c.by_name["evicted"] == s["cache"]["vram_evictions"].get<std::uint64_t>());
  // Every tile drawn was uploaded first; each flow arrow has both ends.
  CHECK(c.by_name["first sampled"] > 0);
  CHECK(c.by_name["first sampled"] <= c.by_name["upload"]);
  CHECK(c.flow_s == c.flow_f);
  CHECK(c.flow_s.size() > 0);
  CHECK(c.flow_s.size() <= c.by_name["first sampled"]);
  CHECK(s["cache"]["vram_evictions"].get<std::uint64_t>() > 0);  // the walk evicts: the count is tested
}

}  // namespace

TEST_CASE("timeline: the JSON parses and its events count what the summary counts (clipmap: cancels, evictions)") {
  const TimelineRun r = timeline_run({});
  check_counts_match(r);
  const nlohmann::json j = nlohmann::json::parse(r.json);
  CHECK(j["otherData"]["clock"] == "simulated");
  // One process per stage, named.
  std::set<std::string> processes;
  for (const auto& e : j["traceEvents"])
    if (e["name"] == "process_name") processes.insert(e["args"]["name"].get<std::string>());
  for (const char* p : {"frames", "request", "queue", "read", "decode", "upload wait", "upload", "first sampled", "evicted"}) {
    CAPTURE(p);
    CHECK(processes.count(p) == 1);
  }
  // Frames follow each other on one track; a stage's slices on one track never overlap.
  std::map<std::pair<int, int>, double> track_end;
  for (const auto& e : j["traceEvents"]) {
    if (e["ph"] != "X") continue;
    if (e["name"] == "frame") CHECK(e["tid"] == 1);
    const auto key = std::make_pair(e["pid"].get<int>(), e["tid"].get<int>());
    const double ts = e["ts"].get<double>(), dur = e["dur"].get<double>();
    if (track_end.count(key)) CHECK(ts >= track_end[key] - 1e-3);
    track_end[key] = std::max(track_end.count(key) ? track_end[key] : 0.0, ts + dur);
  }
}

TEST_CASE("timeline: the report's waterfall shows the tiles a frame waited for, with their stages") {
  const ReplayConfig cfg = load_replay_config("", {});
  const auto scene = make_scene_from_config(cfg);
  TimelineRecorder tl;
  ReplayEnv env;
  env.timeline = &tl;
  run_replay(cfg, timeline_walk(), *scene, env);
  // Frame 0 waits for the whole start-up fill, the earliest requests first.
  const Waterfall w0 = frame_waterfall(tl, 0, "start-up", 10);
  CHECK(w0.rows.size() == 10);
  CHECK(w0.more > 0);
  CHECK(test::contains(w0.title, "Tiles of frame 0 (start-up, 100.0 % blurry)"));
  for (const WaterfallRow& r : w0.rows) {
    REQUIRE(!r.bars.empty());
    CHECK(r.bars.front().stage == WaterfallStage::queue);
    CHECK(r.bars.front().t0_ms == 0.0);
  }
  const int worst = worst_frame(tl, 60);
  REQUIRE(worst >= 60);
  for (const auto& f : tl.frames())
    if (f.measured && f.frame >= 60) CHECK(f.blurry <= tl.frames()[static_cast<std::size_t>(worst)].blurry);
  const std::string svg = waterfall_svg(frame_waterfall(tl, worst, "the most blurry"));
  CHECK(test::contains(svg, "aria-label=\"Tiles of frame " + std::to_string(worst)));
  CHECK(test::contains(svg, "upload wait"));
  // A frame outside the recorded range says so.
  CHECK(test::contains(frame_waterfall(tl, 100000, "x").title, "not in the timeline"));
}

TEST_CASE("timeline: virtual texturing's per-layer evictions and uploads are counted too") {
  const TimelineRun r = timeline_run({"run.system=vt", "vt.pool_pages=96", "view.divisor=16"});
  check_counts_match(r);
}

TEST_CASE("timeline: byte-identical run to run in the simulated clock") {
  const TimelineRun a = timeline_run({"upload.tiles_per_frame=8"});
  const TimelineRun b = timeline_run({"upload.tiles_per_frame=8"});
  CHECK(a.json.size() > 1000);
  CHECK(a.json == b.json);
}

TEST_CASE("timeline: --timeline-frames keeps the requests of those frames and those frames only") {
  TimelineOptions opt;
  parse_timeline_frames("--timeline-frames", "30:59", opt);
  CHECK(opt.first_frame == 30);
  CHECK(opt.last_frame == 59);
  const TimelineRun all = timeline_run({"upload.tiles_per_frame=8"});
  const TimelineRun part = timeline_run({"upload.tiles_per_frame=8"}, opt);
  const EventCounts c = count_events(nlohmann::json::parse(part.json));
  const EventCounts a = count_events(nlohmann::json::parse(all.json));
  CHECK(c.frames == 30);
  REQUIRE(!c.request_frames.empty());
  CHECK(*c.request_frames.begin() >= 30);
  CHECK(*c.request_frames.rbegin() <= 59);
  std::uint64_t in_range = 0;  // the full timeline's requests of those frames: the same ones
  const nlohmann::json all_json = nlohmann::json::parse(all.json);
  for (const auto& e : all_json["traceEvents"])
    if (e["name"] == "request" && e["args"]["frame"] >= 30 && e["args"]["frame"] <= 59) ++in_range;
  CHECK(c.by_name.at("request") == in_range);
  CHECK(c.by_name.at("request") < a.by_name.at("request"));
  CHECK(part.json.size() < all.json.size());
  // Bad ranges name the flag.
  for (const char* bad : {"", "5", "a:b", "9:3", "-1:4", "3:x"}) {
    CAPTURE(bad);
    TimelineOptions o;
    CHECK_THROWS_WITH_AS(parse_timeline_frames("--timeline-frames", bad, o), doctest::Contains("--timeline-frames"), InputError);
  }
  TimelineOptions open_end;
  parse_timeline_frames("--timeline-frames", "100:", open_end);
  CHECK(open_end.first_frame == 100);
  CHECK(open_end.last_frame == std::numeric_limits<int>::max());
}

TEST_CASE("timeline: the size bound is estimated from the frames and the upload budget, and refused with how to narrow it") {
  const ReplayConfig cfg = load_replay_config("", {"upload.tiles_per_frame=16"});
  TimelineOptions opt;
  const TimelineEstimate e = estimate_timeline(cfg, 1000, opt);
  CHECK(e.tiles_per_frame == 16);
  CHECK(e.bytes_per_frame == kTimelineFrameBytes + 16 * kTimelineLifeBytes);
  CHECK(e.bytes == 1000 * e.bytes_per_frame);
  opt.max_bytes = 10 * e.bytes_per_frame;
  CHECK_NOTHROW(check_timeline_bound(cfg, 10, opt));
  CHECK_THROWS_WITH_AS(check_timeline_bound(cfg, 11, opt), doctest::Contains("--timeline-frames 0:9 (10 frames fit)"), InputError);
  opt.first_frame = 5;
  opt.last_frame = 14;
  CHECK_NOTHROW(check_timeline_bound(cfg, 1000, opt));  // ten frames of a long run
  // The measured file stays within the estimate: the bound is an upper bound.
  const TimelineRun r = timeline_run({"upload.tiles_per_frame=8"});
  const ReplayConfig c8 = load_replay_config("", {"upload.tiles_per_frame=8"});
  CHECK(r.json.size() <= estimate_timeline(c8, r.result.summary["trace"]["frames"].get<int>(), {}).bytes);
}

TEST_CASE("timeline CLI: over its bound it is refused before the run (exit 2, the bound named) and an old file stays") {
  const auto dir = std::filesystem::temp_directory_path() / "vtsim-timeline-cli";
  std::filesystem::create_directories(dir);
  const std::string trace = (dir / "walk.csv").string(), out = (dir / "t.json").string(), log = (dir / "log").string();
  save_trace(timeline_walk(), trace);
  { std::ofstream(out) << "previous"; }
  const int rc = test::run_vtsim("replay -q --trace " + trace + " --timeline " + out + " --timeline-max-MB 0.2", log);
  CHECK(rc == 2);
  const std::string msg = test::slurp(log);
  CHECK(test::contains(msg, "vtsim: error: --timeline"));
  CHECK(test::contains(msg, "bound of 0.2 MB"));
  CHECK(test::contains(msg, "--timeline-frames 0:"));
  CHECK(test::slurp(out) == "previous");
  // Narrowed as it says, it runs and writes the file.
  CHECK(test::run_vtsim("replay -q --trace " + trace + " --timeline " + out + " --timeline-max-MB 0.2 --timeline-frames 120:125", log) == 0);
  CHECK(nlohmann::json::parse(test::slurp(out))["traceEvents"].size() > 10);
  CHECK(test::run_vtsim("replay -q --trace " + trace + " --timeline-frames 0:5", log) == 2);
  CHECK(test::contains(test::slurp(log), "--timeline-frames"));
  std::filesystem::remove_all(dir);
}
