// Issue 26, "Nothing lost silently": every reader either reads all of its input, or counts and names
// what it left out, or refuses. One case per bug the issue found, then the policy and the other
// readers (OBJ, heightfield images, configs).
#include <doctest/doctest.h>

#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/image_io.h"
#include "sim/run/replay_config.h"
#include "sim/sweep/sweep.h"
#include "sim/sweep/sweep_spec.h"
#include "sim/trace/trace_import.h"
#include "sim/trace/trace_io.h"
#include "sim/view/mesh.h"
#include "sim/view/scene.h"
#include "trace_test_util.h"

using namespace vtsim;
using vtsim::test::contains;
using vtsim::test::input_error;
using vtsim::test::kData;
using vtsim::test::ScratchDir;
using vtsim::test::vtsim_run;
using vtsim::test::write_file;

namespace {

std::string repairs_read_text(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// Each line of text with its blanks replaced by commas (comment lines kept as they are): the
// "TUM with commas" of issue 26.
std::string repairs_commas(const std::string& text) {
  std::string out, line;
  std::istringstream in(text);
  while (std::getline(in, line)) {
    if (line.empty() || line[0] != '#')
      for (char& c : line)
        if (c == ' ') c = ',';
    out += line + "\n";
  }
  return out;
}

// A TUM file of n poses at `step` units apart, all at the identity orientation.
std::string repairs_tum(int n, const std::string& t0, double step) {
  std::string s = "# timestamp tx ty tz qx qy qz qw\n";
  for (int i = 0; i < n; ++i) s += t0 + std::to_string(static_cast<double>(i) * step) + " 1 2 3 0 0 0 1\n";
  return s;
}

// A native trace of n poses 1/60 s apart, with the pose at `dup` (if >= 0) written twice.
std::string repairs_native(int n, const std::vector<int>& dups) {
  std::string s = "# vtsim-trace v1 image_width=1920 image_height=1080\nt_s,x_m,y_m,z_m,qw,qx,qy,qz,vfov_deg\n";
  for (int i = 0; i < n; ++i) {
    const std::string line = std::to_string(i) + "," + std::to_string(i) + ",0,1.7,1,0,0,0,60\n";
    s += line;
    for (int d : dups)
      if (d == i) s += line;
  }
  return s;
}

}  // namespace

TEST_CASE("issue 26: a TUM file with commas is refused by detection, not read as EuRoC, and --format tum reads it") {
  ScratchDir dir;
  const std::string tum = std::string(kData) + "/tum_fr1_xyz_excerpt.txt";
  const std::string commas = dir.file("tum_commas.txt");
  write_file(commas, repairs_commas(repairs_read_text(tum)));
  const std::string e = input_error([&] { detect_trace_format(commas); });
  CHECK(contains(e, commas + ":4: cannot tell the trace format"));
  CHECK(contains(e, "\"1305031098.6659\" has a fraction"));
  CHECK(contains(e, "give --format tum"));

  ImportOptions o;
  o.format = "tum";
  TraceLoadReport rep_commas, rep_spaces;
  const Trace a = import_trace(commas, o, &rep_commas);
  const Trace b = import_trace(tum, o, &rep_spaces);
  REQUIRE(a.poses.size() == b.poses.size());
  CHECK(a.poses.size() == 200);
  CHECK(rep_commas.repairs.total() == 0);
  for (std::size_t i = 0; i < a.poses.size(); ++i) {
    CHECK(test::same_bits(a.poses[i].t_s, b.poses[i].t_s));
    CHECK(a.poses[i].pos_m == b.poses[i].pos_m);
  }

  vtsim::test::CliRun r = vtsim_run(dir, "trace info " + commas);
  CHECK(r.code == 2);
  CHECK(contains(r.err, "give --format tum"));
  r = vtsim_run(dir, "trace info --format tum " + commas);
  CHECK(r.code == 0);
  CHECK(contains(r.out, "frames:        200"));
  // A whole number of nanoseconds in any spelling is still EuRoC; a fraction of one is not.
  const std::string whole = dir.file("whole.csv");
  write_file(whole, "1.5e9,0,0,0,1,0,0,0\n");
  CHECK(detect_trace_format(whole) == "euroc");
  write_file(whole, "15e-1,0,0,0,1,0,0,0\n");
  CHECK(contains(input_error([&] { detect_trace_format(whole); }), "\"15e-1\" has a fraction"));
}

TEST_CASE("issue 26: EuRoC with times in seconds is refused with the reason and the fix") {
  ScratchDir dir;
  // The excerpt's first columns with the time in seconds (6 decimals), as the file.
  std::string text = "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []\n";
  for (int i = 0; i < 199; ++i)
    text += "1403715524." + std::to_string(100000 + i * 5000) + ",0.5,2.0,0.97,0.161996,0.789985,-0.205376,0.554528\n";
  const std::string secs = dir.file("euroc_seconds.csv");
  write_file(secs, text);
  // Detection: its header names EuRoC, so the reader refuses at the first time.
  std::string e = input_error([&] { load_any_trace(secs); });
  CHECK(contains(e, secs + ":2: field 'timestamp_ns': \"1403715524.100000\" is not an integer"));
  CHECK(contains(e, "look like seconds; write them in nanoseconds"));
  vtsim::test::CliRun r = vtsim_run(dir, "trace info " + secs);
  CHECK(r.code == 2);
  CHECK(contains(r.err, "look like seconds"));

  // Integer milliseconds read as nanoseconds: 199 poses over 0.99 us; the fix is a time scale.
  text = "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []\n";
  for (int i = 0; i < 199; ++i)
    text += std::to_string(1403715524100LL + i * 5) + ",0.5,2.0,0.97,0.161996,0.789985,-0.205376,0.554528\n";
  const std::string ms = dir.file("euroc_ms.csv");
  write_file(ms, text);
  e = input_error([&] { load_any_trace(ms); });
  CHECK(contains(e, ms + ": 199 poses span 9.9e-07 s, a mean rate of 2e+08 Hz, far outside 1 Hz - 10 kHz"));
  CHECK(contains(e, "if the times are in milliseconds rather than nanoseconds, give --time-scale 1e+06"));
  ImportOptions o;
  o.transform.time_scale = 1e6;
  const Trace t = import_trace(ms, o);
  CHECK(t.poses.size() == 199);
  CHECK(t.poses.back().t_s == doctest::Approx(0.99));
}

TEST_CASE("issue 26: implausible time units in TUM are refused, and --time-scale fixes them") {
  ScratchDir dir;
  const std::string ms = dir.file("tum_ms.txt");
  write_file(ms, repairs_tum(50, "", 20.0));  // 20 ms steps written as if seconds: 0.05 Hz
  std::string e = input_error([&] { load_any_trace(ms); });
  CHECK(contains(e, ms + ": 50 poses span 980 s, a mean rate of 0.05 Hz, far outside 1 Hz - 10 kHz: the times are "
                         "probably not in seconds as tum has them"));
  CHECK(contains(e, "if the times are in milliseconds rather than seconds, give --time-scale 0.001"));
  vtsim::test::CliRun r = vtsim_run(dir, "trace import --time-scale 0.001 " + ms + " -o " + dir.file("ok.csv"));
  CHECK(r.code == 0);

  // Every pose at the same time: a duration of 0 s for many poses.
  const std::string zero = dir.file("tum_zero.txt");
  write_file(zero, repairs_tum(20, "", 0.0));
  e = input_error([&] { load_any_trace(zero); });
  CHECK(contains(e, "20 poses span 0 s, a mean rate of inf Hz"));
  CHECK(contains(e, "a duration of 0 s means every pose has the same time"));

  // Fewer than kTimeUnitCheckMinPoses poses say nothing about their rate.
  const std::string few = dir.file("tum_few.txt");
  write_file(few, repairs_tum(static_cast<int>(kTimeUnitCheckMinPoses) - 1, "", 100.0));
  CHECK(load_any_trace(few).poses.size() == static_cast<std::size_t>(kTimeUnitCheckMinPoses - 1));
}

TEST_CASE("issue 26: a native CSV whose header lacks qz is named as native, with what is missing") {
  ScratchDir dir;
  const std::string no_magic = dir.file("no_magic.csv");
  write_file(no_magic, "t_s,x_m,y_m,z_m,qw,qx,qy,vfov_deg\n0,1,2,3,1,0,0,60\n1,1,2,3,1,0,0,60\n");
  CHECK(detect_trace_format(no_magic) == "native");
  std::string e = input_error([&] { load_any_trace(no_magic); });
  CHECK(contains(e, no_magic + ":1: not a native trace: the first line must be '# vtsim-trace v1"));

  const std::string no_qz = dir.file("no_qz.csv");
  write_file(no_qz, "# vtsim-trace v1 image_width=1920 image_height=1080\nt_s,x_m,y_m,z_m,qw,qx,qy,vfov_deg\n"
                    "0,1,2,3,1,0,0,60\n");
  e = input_error([&] { load_any_trace(no_qz); });
  CHECK(contains(e, no_qz + ":2: the column header lacks 'qz': expected 't_s,x_m,y_m,z_m,qw,qx,qy,qz,vfov_deg'"));
  const std::string extra = dir.file("extra.csv");
  write_file(extra, "# vtsim-trace v1 image_width=1920 image_height=1080\nt_s,x_m,y_m,z_m,qw,qx,qy,qz,fov\n"
                    "0,1,2,3,1,0,0,0,60\n");
  CHECK(contains(input_error([&] { load_any_trace(extra); }), "the column header lacks 'vfov_deg'; has \"fov\""));
}

TEST_CASE("issue 26: replay prints a dropped duplicate time, and more than the policy allows needs --allow-repairs") {
  ScratchDir dir;
  const std::string one = dir.file("one_dup.csv");
  write_file(one, repairs_native(30, {5}));
  vtsim::test::CliRun r = vtsim_run(dir, "replay -q --trace " + one);
  CHECK(r.code == 0);
  CHECK(contains(r.err, "vtsim: warning: " + one + ": 1 pose with a repeated time dropped (of 31 poses read)"));

  const std::string two = dir.file("two_dups.csv");
  write_file(two, repairs_native(30, {5, 9}));
  r = vtsim_run(dir, "replay -q --trace " + two);
  CHECK(r.code == 2);
  CHECK(contains(r.err, two + ": 2 of 32 poses dropped (2 with a repeated time): more than 1 pose and more than 1 %"));
  CHECK(contains(r.err, "give --allow-repairs (a sweep spec: allow_repairs = true) to keep the 30 poses left"));
  r = vtsim_run(dir, "replay -q --allow-repairs --trace " + two);
  CHECK(r.code == 0);
  CHECK(contains(r.err, "vtsim: warning: " + two + ": 2 poses with a repeated time dropped (of 32 poses read)"));
  r = vtsim_run(dir, "trace info " + two);
  CHECK(r.code == 2);
  r = vtsim_run(dir, "trace info --allow-repairs " + two);
  CHECK(r.code == 0);
  CHECK(contains(r.out, "repairs:       2 poses with a repeated time dropped"));
}

TEST_CASE("issue 26: a sweep's trace repairs come back as warnings, and the policy applies") {
  ScratchDir dir;
  const std::string one = dir.file("one_dup.csv");
  write_file(one, repairs_native(30, {5}));
  std::vector<std::string> w;
  CHECK(load_sweep_trace({one, false, 1}, &w).poses.size() == 30);
  REQUIRE(w.size() == 1);
  CHECK(w[0] == one + ": 1 pose with a repeated time dropped (of 31 poses read)");
  const std::string two = dir.file("two_dups.csv");
  write_file(two, repairs_native(30, {5, 9}));
  CHECK(contains(input_error([&] { load_sweep_trace({two, false, 1}); }), "2 of 32 poses dropped"));
  // The spec's allow_repairs = true keeps it, the repairs still reported.
  w.clear();
  CHECK(load_sweep_trace({two, false, 1}, &w, true).poses.size() == 30);
  CHECK(w.size() == 1);
  const std::string spec = dir.file("spec.toml");
  write_file(spec, "traces = [\"two_dups.csv\"]\nallow_repairs = true\n[grid]\n\"upload.tiles_per_frame\" = [4]\n");
  CHECK(load_sweep_traces(load_sweep_spec(spec)).front().poses.size() == 30);
  write_file(spec, "traces = [\"two_dups.csv\"]\nallow_repairs = 1\n[grid]\n\"upload.tiles_per_frame\" = [4]\n");
  CHECK(contains(input_error([&] { load_sweep_spec(spec); }), "key 'allow_repairs': expected true or false"));
}

TEST_CASE("repair policy: at most 1 pose or 1 % of the poses read may be dropped") {
  TraceRepairs r;
  r.duplicate_times_dropped = 1;
  CHECK_NOTHROW(check_repairs(r, 3, "f", false));  // one doubled stamp, however short the file
  r.duplicate_times_dropped = 3;
  CHECK_NOTHROW(check_repairs(r, 300, "f", false));  // exactly 1 %
  CHECK(contains(input_error([&] { check_repairs(r, 299, "f", false); }), "f: 3 of 299 poses dropped"));
  CHECK_NOTHROW(check_repairs(r, 299, "f", true));
  r = {};
  r.quats_renormalised = 1000;  // a renormalised quaternion drops nothing: printed, never refused
  CHECK_NOTHROW(check_repairs(r, 1000, "f", false));
  const std::vector<std::string> w = repair_warnings(r, 1000, "f");
  REQUIRE(w.size() == 1);
  CHECK(w[0] == "f: 1000 quaternions renormalised (of 1000 poses read)");
  CHECK(repair_warnings({}, 10, "f").empty());

  // The TUM fr2_desk excerpt's one repeated time (line 10863 of the full file) is still dropped
  // with a warning, not refused.
  TraceLoadReport rep;
  const Trace t = load_any_trace(std::string(kData) + "/tum_fr2_desk_excerpt.txt", {}, &rep);
  CHECK(rep.repairs.duplicate_times_dropped == 1);
  CHECK(t.poses.size() == 199);
}

TEST_CASE("issue 26: the OBJ reader names the triangles it skips, and the mesh scene passes it on") {
  ScratchDir dir;
  const std::string obj = dir.file("degenerate.obj");
  write_file(obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                  "f 1/1 2/2 3/3\nf 1/1 2/2 4/1\n");  // the second is collinear
  ObjStats st;
  load_obj(obj, &st);
  CHECK(st.degenerate_skipped == 1);
  const std::vector<std::string> w = obj_warnings(st, obj);
  REQUIRE(w.size() == 1);
  CHECK(w[0] == obj + ": 1 of 2 triangles skipped: zero area (collinear or repeated corners)");
  SceneConfig cfg;
  cfg.kind = "mesh";
  cfg.file = obj;
  const auto scene = make_scene(cfg);
  CHECK(scene->load_warnings() == w);
  CHECK(make_scene(SceneConfig{})->load_warnings().empty());
}

TEST_CASE("issue 26: a heightmap with more than one channel says which one it used") {
  ScratchDir dir;
  const std::string png = dir.file("rgb.png");
  std::vector<std::uint8_t> px(4 * 4 * 3, 100);
  REQUIRE(image_io::write_file(png, 4, 4, 3, image_io::PixelType::u8, px.data(), false).status ==
          image_io::WriteStatus::ok);
  SceneConfig cfg;
  cfg.kind = "heightfield";
  cfg.file = png;
  const auto scene = make_scene(cfg);
  const std::vector<std::string> w = scene->load_warnings();
  REQUIRE(w.size() == 1);
  CHECK(w[0] == png + ": heights from the first of 3 channels; the other 2 ignored");
}

TEST_CASE("issue 26: configs drop nothing: an unknown key is an error naming the file and line") {
  ScratchDir dir;
  const std::string cfg = dir.file("c.toml");
  write_file(cfg, "[run]\nsystem = \"clipmap\"\nbogus = 3\n");
  CHECK(contains(input_error([&] { load_replay_config(cfg, {}, ""); }), cfg + ":3: unknown config key 'run.bogus'"));
}
