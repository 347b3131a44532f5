// One set of CLI conventions, finished (README.md "Conventions"): view and capacity read -c/--set
// like replay (a flag given wins); progress writes "\r" only to a terminal; empty inputs are errors
// naming the file; `trace cut` crops a trace; `vtsim report` shows each run's vtsim version.
#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <string>

#include "core/error.h"
#include "sim/trace/trace_gen.h"
#include "sim/trace/trace_io.h"
#include "sim/trace/trace_resample.h"
#include "store_test_util.h"
#include "test_util.h"

namespace {

// `sh -c SCRIPT` with $V the CLI, $D the test directory and $SRC the source tree.
vtsim::test::CliRun cf_sh(const std::string& dir, const std::string& script) {
  return vtsim::test::run_capture("V=" + std::string(VTSIM_CLI) + " D=" + dir + " SRC=" + std::string(VTSIM_SOURCE_DIR) +
                                      " sh -c '" + script + "' 2>" + dir + "/.err",
                                  dir + "/.err");
}

nlohmann::json cf_json(const vtsim::test::CliRun& r) {
  CAPTURE(r.err);
  REQUIRE(r.code == 0);
  return nlohmann::json::parse(r.out);
}

}  // namespace

TEST_CASE("capacity: every system reads -c and --set like replay, and a flag given wins over the config") {
  vtsim::test::TempDir td;
  const std::string D = td.path.string();
  std::ofstream(D + "/c.toml") << "[texture]\nwidth = 4096\nheight = 2048\ntile_size = 256\n[clipmap]\nclipsize = 512\n";
  auto j = cf_json(cf_sh(D, "$V capacity -c $D/c.toml --json"));
  CHECK(j["texture"]["width"] == 4096);
  CHECK(j["texture"]["height"] == 2048);
  CHECK(j["tile_size"] == 256);
  CHECK(j["clipsize"] == 512);
  j = cf_json(cf_sh(D, "$V capacity -c $D/c.toml --set texture.width=8192 --width 16384 --clipsize 1024 --json"));
  CHECK(j["texture"]["width"] == 16384);  // the flag wins over --set and the file
  CHECK(j["texture"]["height"] == 16384);  // --width alone: square, as without a config
  CHECK(j["clipsize"] == 1024);
  // vt: texture.tile_size is the page, texture.border its border.
  const auto vt = cf_sh(D, "$V capacity --system vt --set texture.tile_size=256 --set texture.border=4");
  CHECK(vt.code == 0);
  CHECK(vtsim::test::contains(vt.out, "264"));  // 256 + 2 × 4 stored
  // A bad key is named as replay names it.
  const auto bad = cf_sh(D, "$V capacity --set texture.nope=1");
  CHECK(bad.code == 2);
  CHECK(vtsim::test::contains(bad.err, "texture.nope"));
}

TEST_CASE("view: -c and --set give the replay's scene, [view] and tile size, and a flag given wins") {
  vtsim::test::TempDir td;
  const std::string D = td.path.string();
  auto j = cf_json(cf_sh(D, "$V view --set scene.kind=heightfield --set view.divisor=16 --set texture.tile_size=256 "
                            "--pos 4096,4096,300 --json -o $D/v.png"));
  CHECK(j["scene"]["kind"] == "heightfield");
  CHECK(j["buffer"]["divisor"] == 16);
  CHECK(j["tiles"]["tile_size"] == 256);
  std::ofstream(D + "/c.toml") << "[view]\ndivisor = 16\n";
  j = cf_json(cf_sh(D, "$V view -c $D/c.toml --divisor 4 --json -o $D/v.png"));
  CHECK(j["buffer"]["divisor"] == 4);
  CHECK(j["scene"]["kind"] == "plane");
  const auto bad = cf_sh(D, "$V view --set view.divisor=0 -o $D/v2.png");
  CHECK(bad.code == 2);
  CHECK(vtsim::test::contains(bad.err, "view.divisor"));
  CHECK_FALSE(std::filesystem::exists(D + "/v2.png"));
}

TEST_CASE("progress: a log (stderr not a terminal) gets whole lines, never a carriage return") {
  vtsim::test::TempDir td;
  const std::string D = td.path.string();
  REQUIRE(cf_sh(D, "$V trace gen walk --duration 1 -o $D/w.csv").code == 0);
  const auto vt = cf_sh(D, "$V vt compare --traces $D/w.csv --policies none --set run.fps=10 --set view.divisor=32");
  CHECK(vt.code == 0);
  CHECK(vtsim::test::contains(vt.err, "vt compare: w / none\n"));
  CHECK(vt.err.find('\r') == std::string::npos);
  const auto gen = cf_sh(D, "$V store gen -o $D/s.vts --size 1024x1024 --progress");
  CHECK(gen.code == 0);
  CHECK(vtsim::test::contains(gen.err, "100%\n"));
  CHECK(gen.err.find('\r') == std::string::npos);
}

TEST_CASE("empty inputs: an empty access file is an error naming it, not a curve of zeros") {
  vtsim::test::TempDir td;
  const std::string D = td.path.string();
  std::ofstream(D + "/empty.txt").flush();
  std::ofstream(D + "/comments.txt") << "# nothing\n\nframe\n";
  auto r = cf_sh(D, "$V mrc --accesses $D/empty.txt");
  CHECK(r.code == 2);
  CHECK(vtsim::test::contains(r.err, "vtsim: error: " + D + "/empty.txt: is empty"));
  CHECK(r.out.empty());
  r = cf_sh(D, "$V mrc --accesses $D/comments.txt");
  CHECK(r.code == 2);
  CHECK(vtsim::test::contains(r.err, D + "/comments.txt: holds no access"));
  r = cf_sh(D, "$V mrc --accesses - < $D/empty.txt");
  CHECK(r.code == 2);
  CHECK(vtsim::test::contains(r.err, "vtsim: error: -: is empty"));
  // The other readers: an empty trace, sweep spec and store are refused too, each naming the file.
  for (const std::string cmd : {"trace info $D/empty.txt", "sweep $D/empty.txt -o $D/o", "store info $D/empty.txt",
                                "replay --trace $D/empty.txt"}) {
    CAPTURE(cmd);
    r = cf_sh(D, "$V " + cmd);
    CHECK(r.code == 2);
    CHECK(vtsim::test::contains(r.err, D + "/empty.txt"));
  }
  // The one exception: a config file without keys means the defaults (README.md "Conventions").
  r = cf_sh(D, "$V replay --trace $SRC/traces/static.csv -c $D/empty.txt -c $D/comments.txt --set run.fps=2 -q");
  CHECK(r.code == 2);  // "frame" is no TOML: the comments-only file must be TOML comments
  std::ofstream(D + "/toml_comments.toml") << "# only a comment\n\n";
  r = cf_sh(D, "$V replay --trace $SRC/traces/static.csv -c $D/empty.txt -c $D/toml_comments.toml --set run.fps=2 -q");
  CHECK(r.code == 0);
}

TEST_CASE("trace cut: the poses between two times, an interpolated pose at each end, times kept") {
  vtsim::TraceGenParams p = vtsim::default_gen_params("walk");
  p.duration_s = 2.0;
  const vtsim::Trace t = vtsim::generate_trace(p);
  const vtsim::Trace c = vtsim::cut_trace(t, 0.5, 1.25);
  REQUIRE(c.poses.size() >= 2);
  CHECK(c.poses.front().t_s == 0.5);
  CHECK(c.poses.back().t_s == 1.25);
  std::size_t inside = 0;
  for (const vtsim::Pose& q : t.poses) inside += q.t_s > 0.5 && q.t_s < 1.25;
  CHECK(c.poses.size() == inside + 2);
  CHECK(c.poses[1].t_s == t.poses[31].t_s);  // 60 Hz: pose 31 is the first after 0.5 s
  CHECK(c.poses[1].pos_m == t.poses[31].pos_m);
  // An end on a stored pose keeps it (no duplicate), the trace's own end included.
  const vtsim::Trace whole = vtsim::cut_trace(t, t.poses.front().t_s, t.poses.back().t_s);
  CHECK(whole.poses.size() == t.poses.size());
  CHECK_THROWS_WITH_AS(vtsim::cut_trace(t, 1.0, 1.0), doctest::Contains("not before --to"), vtsim::InputError);
  CHECK_THROWS_WITH_AS(vtsim::cut_trace(t, -1.0, 1.0), doctest::Contains("outside the trace"), vtsim::InputError);
  CHECK_THROWS_WITH_AS(vtsim::cut_trace(t, 0.5, 9.0), doctest::Contains("after the trace's end"), vtsim::InputError);

  vtsim::test::TempDir td;
  const std::string D = td.path.string();
  REQUIRE(cf_sh(D, "$V trace gen walk --duration 2 -o $D/w.csv").code == 0);
  auto r = cf_sh(D, "$V trace cut $D/w.csv --from 0.5 --to 1.25 -o $D/c.csv");
  CHECK(r.code == 0);
  const vtsim::Trace back = vtsim::load_trace(D + "/c.csv");
  CHECK(back.poses.size() == c.poses.size());
  CHECK(back.poses.front().t_s == 0.5);
  r = cf_sh(D, "$V trace cut $D/w.csv --from 1 --to 0.5 -o $D/x.csv");
  CHECK(r.code == 2);
  CHECK(vtsim::test::contains(r.err, "vtsim: error: --from: 1 s is not before --to 0.5 s"));
  r = cf_sh(D, "$V trace cut $D/w.csv --from 0 --to 30 -o $D/x.csv");
  CHECK(r.code == 2);
  CHECK(vtsim::test::contains(r.err, "vtsim: error: --to: 30 s is after the trace's end"));
  CHECK_FALSE(std::filesystem::exists(D + "/x.csv"));
}

TEST_CASE("report: the vtsim column shows each run's version from its provenance") {
  vtsim::test::TempDir td;
  const std::string D = td.path.string();
  REQUIRE(cf_sh(D, "$V trace gen walk --duration 1 -o $D/w.csv").code == 0);
  REQUIRE(cf_sh(D, "$V replay --trace $D/w.csv --set run.fps=10 -q --summary $D/s.json").code == 0);
  const auto r = cf_sh(D, "$V report $D/s.json -o $D/r.html");
  CHECK(r.code == 0);
  const std::string html = vtsim::test::slurp(D + "/r.html");
  CHECK(vtsim::test::contains(html, "(commit "));
  CHECK_FALSE(vtsim::test::contains(html, "<td>?</td></tr>"));
}
