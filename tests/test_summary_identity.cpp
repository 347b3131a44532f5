// What a run was (issue 26 §2, docs/metrics.md "What the run was"): a summary records its schema,
// the build, the effective config (every key) and the trace's identity; docs/metrics.md's key
// index lists exactly the keys the summaries emit (each system, both clocks); `vtsim compare`
// leaves wall-clock sections out by default, gives floats a tolerance and integers none, and says
// when two runs' configs or traces differ.
#include <doctest/doctest.h>
#include <fmt/format.h>

#include <set>
#include <string>
#include <vector>

#include "core/hash.h"
#include "real_test_util.h"
#include "sim/compare/compare.h"
#include "sim/run/provenance.h"
#include "sim/run/real_replay.h"
#include "sim/run/replay.h"
#include "sim/report/report_html.h"
#include "sim/trace/trace_gen.h"
#include "sim/trace/trace_import.h"
#include "sim/trace/trace_resample.h"
#include "sim/view/scene.h"
#include "stream/store/tile_store.h"
#include "test_util.h"

using namespace vtsim;
using nlohmann::json;

namespace {

// The first `seconds` of tests/data/town_walk.csv, loaded as a user's file is.
Trace identity_town_walk(double seconds) {
  Trace t = load_any_trace(test::kData + "/town_walk.csv");
  while (t.poses.size() > 2 && t.poses.back().t_s > seconds) t.poses.pop_back();
  return t;
}

json identity_sim_summary(const std::vector<std::string>& sets, const Trace& trace) {
  const ReplayConfig cfg = load_replay_config("", sets);
  return run_replay(cfg, trace, *make_scene_from_config(cfg)).summary;
}

// Every key path of a summary: objects joined by '.', an array as "key[]" and its object
// elements' members as "key[].member"; the config's keys as "config.*" (docs/config.md lists them).
void identity_flatten(const json& j, const std::string& key, std::set<std::string>& out) {
  if (key.rfind("config.", 0) == 0) {
    out.insert("config.*");
    return;
  }
  if (j.is_object()) {
    if (j.empty()) out.insert(key);
    for (const auto& [k, v] : j.items()) identity_flatten(v, key.empty() ? k : key + "." + k, out);
  } else if (j.is_array()) {
    out.insert(key + "[]");
    for (const auto& e : j)
      if (e.is_object()) identity_flatten(e, key + "[]", out);
  } else {
    out.insert(key);
  }
}

// "a.{b,c}.d" -> a.b.d, a.c.d (every group, cartesian).
void identity_expand(const std::string& pattern, std::set<std::string>& out) {
  const auto open = pattern.find('{');
  if (open == std::string::npos) {
    out.insert(pattern);
    return;
  }
  const auto close = pattern.find('}', open);
  REQUIRE(close != std::string::npos);
  const std::string head = pattern.substr(0, open), tail = pattern.substr(close + 1);
  std::string alts = pattern.substr(open + 1, close - open - 1);
  std::size_t p = 0;
  while (true) {
    const auto comma = alts.find(',', p);
    identity_expand(head + alts.substr(p, comma - p) + tail, out);
    if (comma == std::string::npos) break;
    p = comma + 1;
  }
}

// The key index of docs/metrics.md: the lines of its ```keys block, '#' starting a comment.
std::set<std::string> documented_summary_keys() {
  const std::string doc = test::slurp(std::string(VTSIM_SOURCE_DIR) + "/docs/metrics.md");
  const auto begin = doc.find("```keys\n");
  REQUIRE(begin != std::string::npos);
  const auto end = doc.find("```", begin + 8);
  REQUIRE(end != std::string::npos);
  std::set<std::string> keys;
  std::istringstream in(doc.substr(begin + 8, end - begin - 8));
  std::string line;
  while (std::getline(in, line)) {
    line = line.substr(0, line.find('#'));
    line.erase(line.find_last_not_of(" \t") + 1);
    if (!line.empty()) identity_expand(line, keys);
  }
  return keys;
}

ReplayConfig identity_store_cfg(const TileStore& store, const std::vector<std::string>& sets) {
  ReplayConfig c;
  for (const char* s : {"texture.texels_per_m=32", "clipmap.clipsize=256", "view.divisor=16"})
    apply_set(replay_config_table(), c, s);
  for (const std::string& s : sets) apply_set(replay_config_table(), c, s);
  validate(c);
  bind_store_texture(c, store);
  return c;
}

Trace identity_still_trace() {
  TraceGenParams g = default_gen_params("walk");
  g.start_m = {4.0, 16.0};
  g.duration_s = 1.0;
  g.image_width = 640;
  g.image_height = 360;
  return generate_trace(g);
}

CompareReport identity_compare(const json& b, const json& n, CompareOptions opt = {}) {
  return compare_documents(b, "base.json", n, "new.json", opt);
}

const MetricDiff& identity_row(const CompareReport& r, const std::string& key) {
  for (const auto& d : r.rows)
    if (d.key == key) return d;
  FAIL("no row " << key);
  return r.rows.front();
}

}  // namespace

TEST_CASE("summary: the schema, the build, every config key with its effective value, and the trace's identity") {
  const std::string path = test::kData + "/town_walk.csv";
  const Trace trace = identity_town_walk(2.0);
  CHECK(trace.source_path == path);
  CHECK(trace.source_hash == fnv1a64(test::slurp(path)));
  CHECK(resample(trace, 30.0).source_hash == trace.source_hash);  // kept through resampling
  const json s = identity_sim_summary({"scene.kind=town", "disk.preset=hdd", "view.render_threads=0"}, trace);

  CHECK(s["schema"] == kSummarySchema);
  CHECK(s["provenance"]["vtsim_version"] == VTSIM_VERSION);
  const std::string commit = s["provenance"]["vtsim_commit"].get<std::string>();
  // "unknown", or 7 to 40 hex digits with an optional "-dirty" (no std::regex: GCC 12 warns inside
  // it under ASan's -O1, and warnings are errors).
  const std::string hex = commit.size() > 6 && commit.ends_with("-dirty") ? commit.substr(0, commit.size() - 6) : commit;
  const bool is_hex = hex.size() >= 7 && hex.size() <= 40 &&
                      hex.find_first_not_of("0123456789abcdef") == std::string::npos;
  CHECK((commit == "unknown" || is_hex));
  CHECK_FALSE(s["provenance"].contains("machine"));  // the simulated clock measured no machine
  CHECK_FALSE(s.contains("vtsim_version"));           // moved into provenance

  // Every key of the table, typed; the hdd preset is there by name.
  const json& c = s["config"];
  CHECK(c.size() == replay_config_table().fields().size());
  for (const auto& f : replay_config_table().fields()) CHECK_MESSAGE(c.contains(f.key), f.key);
  CHECK(c["disk.preset"] == "hdd");
  CHECK(c["scene.kind"] == "town");
  CHECK(c["texture.tile_size"].is_number_integer());
  CHECK(c["texture.tile_size"] == 128);
  CHECK(c["ram.capacity_MiB"].is_number_float());
  CHECK(c["view.anisotropic"] == false);
  CHECK(c["texture.layers"] == "albedo:rgba8");

  const json& t = s["trace"];
  CHECK(t["path"] == path);
  CHECK(t["content_hash"] == fmt::format("fnv1a64:{:016x}", fnv1a64(test::slurp(path))));
  CHECK(t["poses"] == trace.poses.size());
  CHECK(t["poses_duration_s"] == trace.poses.back().t_s - trace.poses.front().t_s);

  // The HTML report says it too: "hdd" and every key are in it.
  {
    const ReplayConfig cfg = load_replay_config("", {"scene.kind=town", "disk.preset=hdd", "view.render_threads=0"});
    const ReplayResult r = run_replay(cfg, trace, *make_scene_from_config(cfg));
    const std::string html = html_report(r.summary, r.metrics);
    CHECK(test::contains(html, "<tr><th>disk.preset</th><td>hdd</td></tr>"));
    CHECK(test::contains(html, "Effective config: " + std::to_string(replay_config_table().fields().size()) + " keys"));
    CHECK(test::contains(html, fmt::format("fnv1a64:{:016x}", fnv1a64(test::slurp(path)))));
  }

  // A generated trace has no file: no path, no hash; still its poses.
  const Trace gen = identity_still_trace();
  const json g = identity_sim_summary({"view.render_threads=0"}, gen);
  CHECK(g["trace"]["path"] == "");
  CHECK(g["trace"]["content_hash"].is_null());
  CHECK(g["trace"]["poses"] == gen.poses.size());
}

TEST_CASE("summary keys: docs/metrics.md's key index lists every key a summary emits (each system, both clocks) and no other") {
  std::set<std::string> emitted;
  const Trace walk = identity_town_walk(2.0);
  for (const char* system : {"clipmap", "vt"}) {
    CAPTURE(system);
    // Throttled and oversubscribed so the LOD timeline and the pool's policies have entries;
    // metrics.opt for the bounds sections.
    std::vector<std::string> sets = {"scene.kind=town", "view.render_threads=0", std::string("run.system=") + system,
                                     "upload.tiles_per_frame=4", "metrics.opt=true"};
    if (std::string(system) == "vt") sets.push_back("vt.pool_pages=96");
    identity_flatten(identity_sim_summary(sets, walk), "", emitted);
  }
  // The real clock on the small stores, with faults so that the fault examples have members.
  for (const char* system : {"clipmap", "vt"}) {
    CAPTURE(system);
    const bool vt = std::string(system) == "vt";
    const TileStore store = TileStore::open(vt ? test::small_vt_store() : test::small_store());
    const ReplayConfig cfg = identity_store_cfg(store, {std::string("run.system=") + system, "vt.pool_pages=64",
                                                        "io.fault_rate=0.2", "io.max_retries=1"});
    const auto scene = make_scene_from_config(cfg);
    identity_flatten(run_real_replay(cfg, identity_still_trace(), *scene, store).result.summary, "", emitted);
  }
  emitted.insert("trace.speed");  // written by `vtsim replay --speed` (cmd_replay.cpp), not by a library replay
  const std::set<std::string> documented = documented_summary_keys();
  for (const auto& k : emitted) CHECK_MESSAGE(documented.count(k), "emitted but not in docs/metrics.md's key index: " << k);
  // A documented object (a knee that may be null) exists when some emitted key is inside it.
  const auto exists = [&](const std::string& k) {
    const auto it = emitted.lower_bound(k + ".");
    return emitted.count(k) > 0 || (it != emitted.end() && it->rfind(k + ".", 0) == 0);
  };
  for (const auto& k : documented) CHECK_MESSAGE(exists(k), "in docs/metrics.md's key index but never emitted: " << k);
}

TEST_CASE("compare: an unchanged run against its own baseline is OK though its wall clock moved, and --wall-clock compares it") {
  json base = identity_sim_summary({"view.render_threads=0"}, identity_still_trace());
  json now = base;
  now["run"]["wall_s"] = base["run"]["wall_s"].get<double>() * 1.318 + 1.0;  // a loaded machine
  now["provenance"]["vtsim_commit"] = "0123456789ab";
  for (bool strict : {false, true}) {
    CompareOptions o;
    o.strict = strict;
    const CompareReport r = identity_compare(base, now, o);
    CHECK_FALSE(r.failed(strict));
    CHECK(identity_row(r, "run.wall_s").verdict == Verdict::ignored);
    CHECK(identity_row(r, "provenance.vtsim_commit").verdict == Verdict::ignored);
  }
  CompareOptions wc;
  wc.wall_clock = true;
  const CompareReport r = identity_compare(base, now, wc);
  CHECK(identity_row(r, "run.wall_s").verdict == Verdict::worse);
  CHECK(r.failed(false));
  // The same for a real-clock section, and a note says the real clock's figures move.
  base["real_clock"] = {{"late_frames", 3}};
  base["clock"] = "real";
  now["real_clock"] = {{"late_frames", 9}};
  now["clock"] = "real";
  const CompareReport rr = identity_compare(base, now);
  CHECK(identity_row(rr, "real_clock.late_frames").verdict == Verdict::ignored);
  CHECK_FALSE(rr.failed(true));
  bool real_note = false;
  for (const auto& n : rr.notes) real_note |= n.find("real-clock run") != std::string::npos;
  CHECK(real_note);
}

TEST_CASE("compare: floats within max(1e-12, 1e-9 relative) pass, integers compare exactly") {
  const json base = {{"schema", kSummarySchema},
                     {"trace", json::object()},
                     {"popin", {{"blurry_fraction_mean", 0.123}, {"visible_pops", 40}, {"mean_deficit", 0.0}}}};
  json now = base;
  now["popin"]["blurry_fraction_mean"] = 0.123 + 4e-17;
  now["popin"]["mean_deficit"] = 5e-13;
  CompareReport r = identity_compare(base, now);
  CHECK(identity_row(r, "popin.blurry_fraction_mean").verdict == Verdict::within);
  CHECK(identity_row(r, "popin.mean_deficit").verdict == Verdict::within);
  CHECK_FALSE(r.failed(true));
  CompareOptions exact;
  exact.exact_floats = true;
  CHECK(identity_compare(base, now, exact).failed(false));
  // Beyond the band: worse (a blurry fraction is better lower).
  now["popin"]["blurry_fraction_mean"] = 0.123 * (1 + 1e-8);
  CHECK(identity_row(identity_compare(base, now), "popin.blurry_fraction_mean").verdict == Verdict::worse);
  // An integer one off is a change, however large the base.
  now = base;
  now["popin"]["visible_pops"] = 41;
  r = identity_compare(base, now);
  CHECK(identity_row(r, "popin.visible_pops").verdict == Verdict::changed);  // no direction: fewer pops can mean less loaded
  CHECK(r.failed(false));
}

TEST_CASE("compare: differing configs and traces are named in notes and info rows, never a regression") {
  const Trace walk = identity_town_walk(1.0);
  const json base = identity_sim_summary({"scene.kind=town", "view.render_threads=0"}, walk);
  json now = base;
  now["config"]["disk.preset"] = "hdd";
  now["config"]["ram.capacity_MiB"] = 64.0;
  now["trace"]["content_hash"] = "fnv1a64:0000000000000001";
  now["trace"]["path"] = "other.csv";
  const CompareReport r = identity_compare(base, now, CompareOptions{{}, true});
  CHECK_FALSE(r.failed(true));
  CHECK(identity_row(r, "config.disk.preset").verdict == Verdict::info);
  CHECK(identity_row(r, "trace.content_hash").verdict == Verdict::info);
  REQUIRE(r.notes.size() >= 2);
  const std::string text = format_report(r, false, true);
  CHECK(test::contains(text, "note: the two runs' configs differ in 2 keys: disk.preset (nvme -> hdd), ram.capacity_MiB (256.0 -> 64.0)"));
  CHECK(test::contains(text, "note: the two runs' traces differ: base " + test::kData + "/town_walk.csv (fnv1a64:"));
  CHECK(test::contains(text, "new other.csv (fnv1a64:0000000000000001"));
  CHECK(report_json(r, false, true)["notes"].size() == r.notes.size());

  // Same config, same trace under another path: no note about either.
  json moved = base;
  moved["trace"]["path"] = "elsewhere/town_walk.csv";
  const CompareReport same = identity_compare(base, moved);
  for (const auto& n : same.notes) {
    CHECK_FALSE(test::contains(n, "configs differ"));
    CHECK_FALSE(test::contains(n, "traces differ"));
  }

  // A summary from before the schema (no config, no trace identity) still compares, with a note.
  json old = base;
  old.erase("schema");
  old.erase("config");
  old.erase("provenance");
  old["vtsim_version"] = "0.1.0";
  for (const char* k : {"path", "content_hash", "poses", "poses_duration_s"}) old["trace"].erase(k);
  const CompareReport legacy = identity_compare(old, base, CompareOptions{{}, true});
  CHECK_FALSE(legacy.failed(false));
  bool no_config = false;
  for (const auto& n : legacy.notes) no_config |= test::contains(n, "the base summary records no config");
  CHECK(no_config);
  // Another schema version is refused, naming the key.
  json v2 = base;
  v2["schema"] = "vtsim-summary/2";
  CHECK_THROWS_WITH_AS(identity_compare(base, v2), doctest::Contains("key 'schema'"), InputError);
}
