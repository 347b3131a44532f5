// The registry of trace formats (sim/trace/trace_format.h), table-driven: for every registered
// format, a trace written by its writer (export_trace) is detected as that format and imported
// with the defaults gives the trace back; the registry's words (why, names, did-you-mean); what
// export refuses; the CLI's `trace export`.
//
// Round-trip tolerances (docs/traces.md, "Exporters"): native bit for bit; the others positions
// within 1e-9 relative (|d| <= 1e-9 * max(1 m, |p|); exact in practice: the axes are a signed
// permutation), quaternions within 1e-12 per component up to sign, times exactly the original
// rounded to whole nanoseconds (the readers' resolution: TUM's text seconds, EuRoC's integer
// nanoseconds, KITTI's times file), or bit for bit through a KITTI rate.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "sim/trace/trace_export.h"
#include "sim/trace/trace_format.h"
#include "sim/trace/trace_gen.h"
#include "sim/trace/trace_import.h"
#include "sim/trace/trace_io.h"
#include "sim/trace/trace_transform.h"
#include "trace_test_util.h"

using namespace vtsim;
using vtsim::test::contains;
using vtsim::test::input_error;
using vtsim::test::same_bits;
using vtsim::test::ScratchDir;
using vtsim::test::slurp;
using vtsim::test::vtsim_run;
using vtsim::test::write_file;

namespace {

// A walk with turns: 4 s at 60 Hz, turning 270 degrees in 1.5 s from t = 1 s.
Trace formats_walk_with_turns() {
  TraceGenParams p = default_gen_params("turn");
  p.duration_s = 4.0;
  p.event_s = 1.0;
  p.turn_deg = 270.0;
  p.turn_s = 1.5;
  p.heading_deg = 30.0;
  return generate_trace(p);
}

// Poses in general orientation (every roll, pitch and yaw, including half turns with w = 0 and a
// negative w), positions from -5e3 to 6e6 m and near 0, irregular times in whole nanoseconds
// from 0 (steps from 1 ns to 50 ms), a vfov and image size only the native format keeps.
Trace formats_general_trace() {
  std::uint64_t s = 12345;
  const auto next = [&s] {  // splitmix64, in [-1, 1)
    std::uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return static_cast<double>(z >> 11) / 4503599627370496.0 - 1.0;
  };
  Trace t;
  t.name = "general orientation";
  t.image_width = 640;
  t.image_height = 480;
  const glm::dquat special[] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}, {-0.6, 0, 0.8, 0}};
  std::int64_t ns = 0;
  for (int i = 0; i < 300; ++i) {
    Pose p;
    p.t_s = static_cast<double>(ns) / 1e9;
    ns += i % 7 == 3 ? 1 : 1 + static_cast<std::int64_t>((next() + 1.0) * 25e6);
    p.pos_m = {-5000.0 + 33.3 * next(), 6e6 * next(), i % 10 == 0 ? 0.0 : 1e-3 * next()};
    p.q = i < 5 ? special[i] : glm::normalize(glm::dquat(next(), next(), next(), next()));
    p.vfov_deg = 47.5;
    t.poses.push_back(p);
  }
  return t;
}

// The files a format's export writes: the poses and, for a format whose poses carry no time, the
// times.
struct FormatFiles {
  std::string poses, times;
};

FormatFiles formats_export(const ScratchDir& dir, const TraceFormat& f, const Trace& t, const std::string& stem) {
  FormatFiles w{dir.file(stem + "." + std::string(f.name)), f.separate_times ? dir.file(stem + "_times.txt") : ""};
  ExportOptions o;
  o.times_path = w.times;
  export_trace(t, f.name, w.poses, o);
  return w;
}

// The original time rounded to whole nanoseconds, as a reader rebased at 0 gives it back. For
// i / 60 s and n ns / 1e9 the product with 1e9 is never near a tie.
double formats_ns_time(double t_s) { return static_cast<double>(std::llround(t_s * 1e9)) / 1e9; }

void formats_check_round_trip(const TraceFormat& f, const Trace& a, const Trace& b) {
  REQUIRE(b.poses.size() == a.poses.size());
  const bool native = f.name == "native";
  if (native) {
    CHECK(b.name == a.name);
    CHECK(b.image_width == a.image_width);
    CHECK(b.image_height == a.image_height);
  } else {  // the format carries no name, image size or vfov: the import's defaults
    CHECK(b.image_width == 1920);
    CHECK(b.image_height == 1080);
  }
  int bad = 0;
  for (std::size_t i = 0; i < a.poses.size() && bad < 5; ++i) {
    CAPTURE(i);
    const Pose& p = a.poses[i];
    const Pose& q = b.poses[i];
    bool ok = true;
    if (native) {
      ok = same_bits(q.t_s, p.t_s) && same_bits(q.vfov_deg, p.vfov_deg);
      for (int k = 0; k < 3; ++k) ok = ok && same_bits(q.pos_m[k], p.pos_m[k]);
      for (int k = 0; k < 4; ++k) ok = ok && same_bits(q.q[k], p.q[k]);
    } else {
      ok = q.t_s == formats_ns_time(p.t_s) && q.vfov_deg == 60.0;
      for (int k = 0; k < 3; ++k)
        ok = ok && std::abs(q.pos_m[k] - p.pos_m[k]) <= 1e-9 * std::max(1.0, std::abs(p.pos_m[k]));
      double plus = 0.0, minus = 0.0;  // q and -q are the same rotation
      for (int k = 0; k < 4; ++k) {
        plus = std::max(plus, std::abs(q.q[k] - p.q[k]));
        minus = std::max(minus, std::abs(q.q[k] + p.q[k]));
      }
      ok = ok && std::min(plus, minus) <= 1e-12;
    }
    if (!ok) {
      ++bad;
      CAPTURE(p.t_s);
      CAPTURE(q.t_s);
      CAPTURE(p.pos_m.x);
      CAPTURE(q.pos_m.x);
      CAPTURE(p.q.w);
      CAPTURE(q.q.w);
      FAIL_CHECK("pose differs beyond the stated tolerance");
    }
  }
}

// The numbers of text (separated by spaces, commas and newlines) are `want`, each within 1e-15:
// rounding of the axes' quaternions leaves ~2e-16 where an exact 0 or 1 would be.
void formats_check_numbers(const std::string& text, const std::vector<double>& want) {
  CAPTURE(text);
  std::vector<double> got;
  std::size_t i = 0;
  while (i < text.size()) {
    const std::size_t e = text.find_first_of(" ,\n", i);
    const std::string tok = text.substr(i, e == std::string::npos ? std::string::npos : e - i);
    if (!tok.empty()) got.push_back(std::stod(tok));
    if (e == std::string::npos) break;
    i = e + 1;
  }
  REQUIRE(got.size() == want.size());
  for (std::size_t k = 0; k < got.size(); ++k) {
    CAPTURE(k);
    CHECK(std::abs(got[k] - want[k]) <= 1e-15 * std::max(1.0, std::abs(want[k])));
  }
}

}  // namespace

TEST_CASE("every trace format: what its writer wrote is detected as it and imports back with the defaults") {
  ScratchDir dir;
  const Trace walk = formats_walk_with_turns();
  const Trace general = formats_general_trace();
  REQUIRE(trace_formats().entries().size() >= 4);
  for (const TraceFormat& f : trace_formats().entries()) {
    CAPTURE(f.name);
    for (const Trace* t : {&walk, &general}) {
      CAPTURE(t->name);
      const FormatFiles w = formats_export(dir, f, *t, t == &walk ? "walk" : "general");
      CHECK(detect_trace_format(w.poses) == f.name);
      TraceLoadReport rep;
      ImportOptions o;
      o.kitti_times_path = w.times;
      const Trace back = import_trace(w.poses, o, &rep);
      CHECK(rep.format == f.name);
      CHECK(rep.repairs.total() == 0);  // the writer writes nothing a reader must repair
      formats_check_round_trip(f, *t, back);
      // Strict reading accepts it too.
      o.read.strict = true;
      CHECK(import_trace(w.poses, o).poses.size() == t->poses.size());
    }
  }
}

TEST_CASE("formats without times in their poses: a rate that gives the times back round-trips them bit for bit") {
  ScratchDir dir;
  const Trace walk = formats_walk_with_turns();  // t = i / 60
  for (const TraceFormat& f : trace_formats().entries()) {
    if (!f.separate_times) continue;
    CAPTURE(f.name);
    const std::string path = dir.file("rate." + std::string(f.name));
    ExportOptions eo;
    eo.rate_hz = 60.0;
    export_trace(walk, f.name, path, eo);
    ImportOptions io;
    io.kitti_rate_hz = 60.0;
    const Trace back = import_trace(path, io);
    REQUIRE(back.poses.size() == walk.poses.size());
    for (std::size_t i = 0; i < walk.poses.size(); ++i) CHECK(same_bits(back.poses[i].t_s, walk.poses[i].t_s));
    // A rate that does not give the times back is refused, naming the first pose it misses.
    eo.rate_hz = 50.0;
    CHECK(contains(input_error([&] { export_trace(walk, f.name, path, eo); }), path + " pose 1: time"));
    eo.rate_hz = 60.0;
    CHECK(contains(input_error([&] { export_trace(formats_general_trace(), f.name, path, eo); }),
                   "the rate does not give the times back"));
  }
}

TEST_CASE("trace formats: each entry has a name, a one-line why, default axes that parse, and its hooks") {
  for (const TraceFormat& f : trace_formats().entries()) {
    CAPTURE(f.name);
    CHECK(!f.name.empty());
    CHECK(!f.why.empty());
    CHECK(f.why.find('\n') == std::string_view::npos);
    CHECK(f.why.size() <= 120);
    CHECK((f.sniff != nullptr));
    CHECK((f.read != nullptr));
    CHECK((f.write != nullptr));
    CHECK(parse_world_axes(f.axes.world, "world").spec.size() == 3);
    CHECK(parse_camera_axes(f.axes.camera, "camera").spec.size() == 3);
    CHECK(&parse_trace_format(f.name, "--format") == &f);
  }
  CHECK(trace_formats().names() == "native, tum, kitti, euroc");
}

TEST_CASE("unknown trace format names give a did-you-mean error naming the option") {
  const std::string list = "(one of: " + trace_formats().names();
  std::string e = input_error([] { parse_trace_format("tun", "--format"); });
  CHECK(e == "--format: unknown trace format 'tun' " + list + "; did you mean 'tum'?)");
  e = input_error([] { parse_trace_format("csv", "--format"); });
  CHECK(e == "--format: unknown trace format 'csv' " + list + ")");
  ImportOptions o;
  o.format = "eroc";
  e = input_error([&] { import_trace(vtsim::test::kData + "/euroc_V1_02_excerpt.csv", o); });
  CHECK(contains(e, "format: unknown trace format 'eroc'"));
  CHECK(contains(e, "did you mean 'euroc'?"));
  ScratchDir dir;
  e = input_error([&] { export_trace(formats_walk_with_turns(), "kiti", dir.file("x.txt")); });
  CHECK(contains(e, "did you mean 'kitti'?"));
}

TEST_CASE("detection: a line no format claims is an error listing the formats' rules, as before the registry") {
  ScratchDir dir;
  write_file(dir.file("odd.txt"), "# five numbers\n1 2 3 4 5\n");
  CHECK(input_error([&] { detect_trace_format(dir.file("odd.txt")); }) ==
        dir.file("odd.txt") + ":2: cannot tell the trace format from this line (5 fields: tum has 8, kitti 12, "
                              "euroc >= 8 comma-separated (an integer time)); give --format");
  write_file(dir.file("odd.csv"), "1,2,3\n");
  CHECK(contains(input_error([&] { detect_trace_format(dir.file("odd.csv")); }), ":1: cannot tell the trace format from this line (3 fields:"));
  // The comment rules: the magic line only as line 1; EuRoC's header anywhere before the data.
  write_file(dir.file("late_magic.txt"), "\n# vtsim-trace v1\n1 2 3 4 5 6 7 8\n");
  CHECK(detect_trace_format(dir.file("late_magic.txt")) == "tum");
  write_file(dir.file("magic_euroc.txt"), "# vtsim-trace p_RS_R_x\n");
  CHECK(detect_trace_format(dir.file("magic_euroc.txt")) == "native");
  write_file(dir.file("euroc_header.txt"), "# a\n#timestamp, p_RS_R_x [m]\n1 2 3\n");
  CHECK(detect_trace_format(dir.file("euroc_header.txt")) == "euroc");
}

TEST_CASE("export writes each format's own layout, units and axes") {
  ScratchDir dir;
  // An identity FLU camera (looking east, upright) at (1, 2, 3), then the same 0.5 s later.
  Trace t;
  Pose p;
  p.pos_m = {1.0, 2.0, 3.0};
  t.poses = {p, p};
  t.poses[1].t_s = 0.5;
  t.name = "two";
  ExportOptions o;
  export_trace(t, "native", dir.file("a.csv"), o);
  CHECK(slurp(dir.file("a.csv")) == format_trace(t));
  // TUM (z-up, optical): the optical axes of that camera are x right = -y, y down = -z,
  // z forward = +x; their quaternion x y z w.
  export_trace(t, "tum", dir.file("a.tum"), o);
  CHECK(slurp(dir.file("a.tum")) ==
        "# timestamp tx ty tz qx qy qz qw\n0 1 2 3 -0.5 0.5 -0.5 0.5\n0.5 1 2 3 -0.5 0.5 -0.5 0.5\n");
  // EuRoC (z-up, imu-urf: x up, y right, z forward): integer nanoseconds, w first; the body axes
  // are a half turn about (1, 0, 1) / sqrt(2) from the world's.
  export_trace(t, "euroc", dir.file("a.euroc"), o);
  const std::string euroc = slurp(dir.file("a.euroc"));
  CHECK(euroc.rfind("#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], "
                    "q_RS_z []\n0,1,2,3,0,0.70710678118654",
                    0) == 0);
  CHECK(contains(euroc, "\n500000000,1,2,3,0,0.70710678118654"));
  const double h = std::sqrt(0.5);
  formats_check_numbers(euroc.substr(euroc.find('\n') + 1), {0, 1, 2, 3, 0, h, 0, h, 5e8, 1, 2, 3, 0, h, 0, h});
  // KITTI (y-down world: x east, y down, z north; optical camera): R's columns are the camera's
  // right (south: 0 0 -1), down (0 1 0) and forward (east: 1 0 0) in that world; t = (1, -3, 2).
  o.times_path = dir.file("a_times.txt");
  export_trace(t, "kitti", dir.file("a.kitti"), o);
  const std::vector<double> row = {0, 0, 1, 1, 0, 1, 0, -3, -1, 0, 0, 2};
  std::vector<double> rows = row;
  rows.insert(rows.end(), row.begin(), row.end());
  formats_check_numbers(slurp(dir.file("a.kitti")), rows);
  CHECK(slurp(dir.file("a_times.txt")) == "0\n0.5\n");
}

TEST_CASE("export in other axes: importing with the same axes gives the trace back") {
  ScratchDir dir;
  const Trace walk = formats_walk_with_turns();
  ExportOptions eo;
  eo.world_axes = "y-up";
  eo.camera_axes = "opengl";
  export_trace(walk, "tum", dir.file("gl.txt"), eo);
  ImportOptions io;
  io.transform.world_axes = "y-up";
  io.transform.camera_axes = "opengl";
  formats_check_round_trip(parse_trace_format("tum", "format"), walk, import_trace(dir.file("gl.txt"), io));
  const Trace plain = import_trace(dir.file("gl.txt"));  // read with TUM's own axes: another trace
  CHECK(plain.poses[0].pos_m != walk.poses[0].pos_m);
  eo.camera_axes = "XYZ";
  CHECK(contains(input_error([&] { export_trace(walk, "tum", dir.file("gl.txt"), eo); }), "camera_axes"));
}

TEST_CASE("export refuses what the format cannot give back, naming the option or the pose") {
  ScratchDir dir;
  const Trace walk = formats_walk_with_turns();
  const std::string out = dir.file("out.txt");
  ExportOptions o;
  CHECK(contains(input_error([&] { export_trace(walk, "kitti", out, o); }),
                 "times: kitti poses carry no time: give a times file"));
  o.times_path = dir.file("t.txt");
  o.rate_hz = 60.0;
  CHECK(contains(input_error([&] { export_trace(walk, "kitti", out, o); }), "(exactly one)"));
  CHECK(contains(input_error([&] { export_trace(walk, "tum", out, o); }),
                 "times: tum poses carry their own times: a times file or a rate is for formats whose poses carry "
                 "none (kitti)"));
  o.times_path.clear();
  CHECK(contains(input_error([&] { export_trace(walk, "euroc", out, o); }), "rate: euroc poses carry their own times"));
  o.rate_hz = -1.0;
  CHECK(contains(input_error([&] { export_trace(walk, "kitti", out, o); }), "rate: -1 Hz is not in (0, 1e6]"));
  o.rate_hz = 0.0;
  o.times_path = out;
  CHECK(contains(input_error([&] { export_trace(walk, "kitti", out, o); }), "is the poses' output too"));
  // Two poses less than half a nanosecond apart: valid, kept by native, but every other format
  // reads whole nanoseconds and would drop one.
  Trace close = walk;
  close.poses[1].t_s = 2e-10;
  for (const TraceFormat& f : trace_formats().entries()) {
    CAPTURE(f.name);
    ExportOptions fo;
    if (f.separate_times) fo.times_path = dir.file("close_times.txt");
    if (f.name == "native") {
      export_trace(close, f.name, out, fo);
      CHECK(load_trace(out).poses[1].t_s == 2e-10);
    } else {
      CHECK(contains(input_error([&] { export_trace(close, f.name, out, fo); }),
                     out + " pose 1: time 2e-10 s is within half a nanosecond of the previous pose's"));
    }
  }
  Trace invalid = walk;
  invalid.poses[3].t_s = invalid.poses[2].t_s;
  CHECK(contains(input_error([&] { export_trace(invalid, "tum", out); }), out + " pose 3"));
  CHECK(contains(input_error([&] { export_trace(walk, "tum", dir.file("no/such/dir.txt")); }), "cannot create"));
}

TEST_CASE("docs/traces.md lists every trace format with its why, as the registry prints it, and shows format_tum.cpp") {
  const std::string doc = slurp(std::string(VTSIM_SOURCE_DIR) + "/docs/traces.md");
  CHECK_MESSAGE(contains(doc, trace_formats().markdown("format")),
                "docs/traces.md, 'Adding a trace format', should hold:\n" << trace_formats().markdown("format"));
  // The example file is shown as it is.
  CHECK(contains(doc, "```cpp\n" + slurp(std::string(VTSIM_SOURCE_DIR) + "/src/sim/trace/impl/format_tum.cpp") + "```\n"));
}

TEST_CASE("cli: trace export writes what trace import reads back - help and errors from the registry") {
  ScratchDir dir;
  const std::string walk = dir.file("walk.csv");
  REQUIRE(vtsim_run(dir, "trace gen turn --duration 3 --at 1 -o " + walk).code == 0);
  const Trace original = load_trace(walk);
  for (const TraceFormat& f : trace_formats().entries()) {
    CAPTURE(f.name);
    const std::string out = dir.file("out." + std::string(f.name));
    const std::string times = f.separate_times ? " --times " + dir.file("out_times.txt") : "";
    vtsim::test::CliRun r = vtsim_run(dir, "trace export --format " + std::string(f.name) + " " + walk + " -o " + out + times);
    REQUIRE(r.code == 0);
    CHECK(contains(r.err, "wrote " + std::to_string(original.poses.size()) + " poses (" + std::string(f.name) + ")"));
    const std::string back = dir.file("back.csv");
    r = vtsim_run(dir, "trace import " + out + times + " -o " + back);
    REQUIRE(r.code == 0);
    formats_check_round_trip(f, original, load_trace(back));
  }
  vtsim::test::CliRun r = vtsim_run(dir, "trace export --help");
  CHECK(r.code == 0);
  CHECK(contains(r.out, "Output format: " + trace_formats().names()));
  CHECK(contains(r.out, "--times"));
  r = vtsim_run(dir, "trace import --help");
  CHECK(contains(r.out, "Input format: auto, " + trace_formats().names()));
  r = vtsim_run(dir, "trace info --help");
  CHECK(contains(r.out, "Input format: auto, " + trace_formats().names()));
  r = vtsim_run(dir, "trace export --format kiti " + walk + " -o " + dir.file("x.txt"));
  CHECK(r.code == 2);
  CHECK(contains(r.err, "--format: unknown trace format 'kiti'"));
  CHECK(contains(r.err, "did you mean 'kitti'?"));
  r = vtsim_run(dir, "trace import --format natve " + walk + " -o " + dir.file("x.csv"));
  CHECK(r.code == 2);
  CHECK(contains(r.err, "did you mean 'native'?"));
  r = vtsim_run(dir, "trace export --format kitti " + walk + " -o " + dir.file("x.txt"));
  CHECK(r.code == 2);
  CHECK(contains(r.err, "kitti poses carry no time"));
  r = vtsim_run(dir, "trace export --format kitti --rate 60 " + walk + " -o " + dir.file("x.txt"));
  CHECK(r.code == 0);
}
