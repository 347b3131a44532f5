// Native trace format: exact round trip, accepted variations, and every kind of bad input.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <string>

#include "sim/trace/trace_gen.h"
#include "sim/trace/trace_io.h"
#include "trace_test_util.h"

using namespace vtsim;
using vtsim::test::contains;
using vtsim::test::input_error;
using vtsim::test::same_bits;
using vtsim::test::ScratchDir;
using vtsim::test::write_file;

namespace {

const std::string kHead =
    "# vtsim-trace v1 image_width=1920 image_height=1080\n"
    "t_s,x_m,y_m,z_m,qw,qx,qy,qz,vfov_deg\n";
const std::string kRow0 = "0,1,2,3,1,0,0,0,60\n";
const std::string kRow1 = "0.5,1,2,3,1,0,0,0,60\n";

void check_identical(const Trace& a, const Trace& b) {
  REQUIRE(a.poses.size() == b.poses.size());
  CHECK(a.image_width == b.image_width);
  CHECK(a.image_height == b.image_height);
  CHECK(a.name == b.name);
  for (std::size_t i = 0; i < a.poses.size(); ++i) {
    const Pose& p = a.poses[i];
    const Pose& q = b.poses[i];
    const double va[] = {p.t_s, p.pos_m.x, p.pos_m.y, p.pos_m.z, p.q.w, p.q.x, p.q.y, p.q.z, p.vfov_deg};
    const double vb[] = {q.t_s, q.pos_m.x, q.pos_m.y, q.pos_m.z, q.q.w, q.q.x, q.q.y, q.q.z, q.vfov_deg};
    for (int k = 0; k < 9; ++k) {
      INFO("pose " << i << " field " << k << ": " << va[k] << " vs " << vb[k]);
      REQUIRE(same_bits(va[k], vb[k]));
    }
  }
}

// A trace whose doubles have no short decimal form, including -0, tiny and huge magnitudes.
Trace awkward_trace() {
  Trace t;
  t.image_width = 3840;
  t.image_height = 7;
  t.name = "awkward, with commas = and \"quotes\"";
  std::uint64_t s = 0x9E3779B97F4A7C15ull;  // splitmix64: deterministic pseudo-random values
  const auto next = [&] {
    s += 0x9E3779B97F4A7C15ull;
    std::uint64_t z = s;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return static_cast<double>((z ^ (z >> 31)) >> 11) / 9007199254740992.0;  // [0, 1)
  };
  double time = -1.0 / 3.0;
  for (int i = 0; i < 500; ++i) {
    Pose p;
    time += 1e-9 + next() / 7.0;
    p.t_s = time;
    p.pos_m = {(next() - 0.5) * 2e9, next() * 1e-300, i == 0 ? -0.0 : (next() - 0.5) / 3.0};
    glm::dquat q(next() - 0.5, next() - 0.5, next() - 0.5, next() - 0.5);
    p.q = glm::normalize(q);
    p.vfov_deg = kMinVfov_deg + next() * (kMaxVfov_deg - kMinVfov_deg);
    t.poses.push_back(p);
  }
  return t;
}

}  // namespace

TEST_CASE("native format round-trips bit-exactly") {
  ScratchDir dir;
  SUBCASE("awkward doubles") {
    const Trace t = awkward_trace();
    save_trace(t, dir.file("a.csv"));
    check_identical(t, load_trace(dir.file("a.csv")));
    // And the text is stable: writing what was read gives the same bytes.
    CHECK(format_trace(load_trace(dir.file("a.csv"))) == format_trace(t));
  }
  SUBCASE("every generated kind") {
    for (const TraceGenerator& k : trace_generators().entries()) {
      TraceGenParams p = default_gen_params(k.name);
      p.duration_s = 12.0;
      const Trace t = generate_trace(p);
      save_trace(t, dir.file("g.csv"));
      TraceLoadReport rep;
      check_identical(t, load_trace(dir.file("g.csv"), {}, &rep));
      CHECK(rep.repairs.total() == 0);
      CHECK(rep.format == "native");
    }
  }
}

TEST_CASE("native reader accepts CRLF, comments, blank lines and a name") {
  ScratchDir dir;
  const std::string text =
      "# vtsim-trace v1 image_width=640 image_height=480\r\n"
      "# name: my trace, hand written\r\n"
      "# another comment\r\n"
      "\r\n"
      " t_s , x_m,y_m,z_m,qw,qx,qy,qz,vfov_deg\r\n"
      "0,1,2,3,1,0,0,0,60\r\n"
      "  # a comment between poses\r\n"
      "+0.25, 1e3 ,2,3,1,0,0,0,45.5\r\n"
      "\r\n\r\n   \r\n";
  write_file(dir.file("crlf.csv"), text);
  const Trace t = load_trace(dir.file("crlf.csv"));
  CHECK(t.image_width == 640);
  CHECK(t.image_height == 480);
  CHECK(t.name == "my trace, hand written");
  REQUIRE(t.poses.size() == 2);
  CHECK(t.poses[1].t_s == 0.25);
  CHECK(t.poses[1].pos_m.x == 1000.0);
  CHECK(t.poses[1].vfov_deg == 45.5);
  // A UTF-8 byte-order mark (Windows editors) is skipped.
  write_file(dir.file("bom.csv"), "\xEF\xBB\xBF" + kHead + kRow0);
  CHECK(load_trace(dir.file("bom.csv")).poses.size() == 1);
  // No final newline is fine too.
  write_file(dir.file("nofinal.csv"), kHead + kRow0 + "0.5,1,2,3,1,0,0,0,60");
  CHECK(load_trace(dir.file("nofinal.csv")).poses.size() == 2);
}

TEST_CASE("native reader: quaternion and time repairs are counted, and errors under strict") {
  ScratchDir dir;
  SUBCASE("near-unit quaternion") {
    write_file(dir.file("q.csv"), kHead + kRow0 + "0.5,1,2,3,1.0005,0,0,0,60\n");
    TraceLoadReport rep;
    const Trace t = load_trace(dir.file("q.csv"), {}, &rep);
    CHECK(rep.repairs.quats_renormalised == 1);
    CHECK(t.poses[1].q.w == 1.0);
    TraceReadOptions strict;
    strict.strict = true;
    const std::string e = input_error([&] { load_trace(dir.file("q.csv"), strict); });
    CHECK(contains(e, dir.file("q.csv") + ":4:"));
    CHECK(contains(e, "strict"));
  }
  SUBCASE("duplicate time") {
    write_file(dir.file("d.csv"), kHead + kRow0 + "0,5,5,5,1,0,0,0,60\n" + kRow1);
    TraceLoadReport rep;
    const Trace t = load_trace(dir.file("d.csv"), {}, &rep);
    CHECK(rep.repairs.duplicate_times_dropped == 1);
    REQUIRE(t.poses.size() == 2);
    CHECK(t.poses[0].pos_m.x == 1.0);  // the first of the two is kept
    TraceReadOptions strict;
    strict.strict = true;
    const std::string e = input_error([&] { load_trace(dir.file("d.csv"), strict); });
    CHECK(contains(e, dir.file("d.csv") + ":4:"));
    CHECK(contains(e, "duplicate time"));
  }
}

TEST_CASE("native reader: bad input names the file and line") {
  ScratchDir dir;
  struct Case {
    const char* label;
    std::string text;
    int line;          // expected line in the message (0: the file only)
    const char* what;  // expected words
  };
  const std::string huge_line(70 * 1024, '1');
  const Case cases[] = {
      {"NaN", kHead + kRow0 + "0.5,nan,2,3,1,0,0,0,60\n", 4, "not finite"},
      {"inf", kHead + kRow0 + "0.5,1,inf,3,1,0,0,0,60\n", 4, "not finite"},
      {"-infinity time", kHead + "-infinity,1,2,3,1,0,0,0,60\n", 3, "not finite"},
      {"overflow", kHead + kRow0 + "0.5,1e400,2,3,1,0,0,0,60\n", 4, "out of range"},
      {"time backwards", kHead + kRow1 + kRow0, 4, "time goes backwards"},
      {"quaternion far from unit", kHead + kRow0 + "0.5,1,2,3,1.1,0,0,0,60\n", 4, "quaternion norm"},
      {"zero quaternion", kHead + kRow0 + "0.5,1,2,3,0,0,0,0,60\n", 4, "zero quaternion"},
      {"missing column", kHead + kRow0 + "0.5,1,2,3,1,0,0,0\n", 4, "expected 9 fields"},
      {"extra column", kHead + kRow0 + "0.5,1,2,3,1,0,0,0,60,7\n", 4, "expected 9 fields"},
      {"empty field", kHead + "0,1,,3,1,0,0,0,60\n", 3, "empty"},
      {"text in a number", kHead + "0,1,2,3m,1,0,0,0,60\n", 3, "not a number"},
      {"empty file", "", 1, "empty file"},
      {"header only", kHead, 2, "no poses"},
      {"no column header", "# vtsim-trace v1 image_width=1 image_height=1\n0,1,2,3,1,0,0,0,60\n", 2,
       "column header"},
      {"wrong magic", "t_s,x_m\n", 1, "not a native trace"},
      {"version", "# vtsim-trace v2 image_width=1 image_height=1\n", 1, "version"},
      {"unknown key", "# vtsim-trace v1 image_width=1 image_height=1 fps=3\n", 1, "unknown"},
      {"image too large", "# vtsim-trace v1 image_width=100000 image_height=1\n", 1, "image_width"},
      {"missing image size", "# vtsim-trace v1 image_width=10\n", 1, "image_height"},
      {"vfov", kHead + "0,1,2,3,1,0,0,0,180\n", 3, "vfov"},
      {"vfov the camera refuses", kHead + "0,1,2,3,1,0,0,0,179.5\n", 3, "vfov"},  // replay would fail later
      {"vfov too narrow", kHead + "0,1,2,3,1,0,0,0,0.001\n", 3, "vfov"},
      {"coordinate too large", kHead + "0,1e11,2,3,1,0,0,0,60\n", 3, "not within"},
      {"time too large", kHead + "1e11,1,2,3,1,0,0,0,60\n", 3, "not within"},
      {"time beyond the tick clock", kHead + "0,1,2,3,1,0,0,0,60\n9.3e9,1,2,3,1,0,0,0,60\n", 4, "not within"},
      {"binary garbage", kHead + kRow0 + std::string("\x7f" "ELF\x02\x01\x00\x00\x00", 9) + "\n", 4, "NUL byte"},
      {"non-UTF-8", kHead + kRow0 + "0.5,1,2,3,1,0,0,0,60 \xff\xfe\n", 4, "invalid UTF-8"},
      {"overlong UTF-8", kHead + "# \xc0\xaf\n" + kRow0, 3, "invalid UTF-8"},
      {"huge line", kHead + kRow0 + huge_line + "\n", 4, "longer than 65536 bytes"},
      {"lone CR inside a line", kHead + "0,1,2\r,3,1,0,0,0,60\n", 3, "not a number"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.label);
    const std::string path = dir.file("bad.csv");
    write_file(path, c.text);
    const std::string e = input_error([&] { load_trace(path); });
    CAPTURE(e);
    CHECK(contains(e, c.line ? path + ":" + std::to_string(c.line) + ":" : path));
    CHECK(contains(e, c.what));
  }
}

TEST_CASE("native reader: file-level limits") {
  ScratchDir dir;
  CHECK(contains(input_error([&] { load_trace(dir.file("missing.csv")); }), "cannot open"));
  CHECK(contains(input_error([&] { load_trace(dir.path().string()); }), "is a directory, not a file"));
  CHECK(contains(input_error([&] { load_trace("/dev/zero"); }), "/dev/zero: not a regular file (a FIFO, socket or device)"));
  write_file(dir.file("big.csv"), kHead + kRow0 + kRow1);
  TraceReadOptions small;
  small.limits.max_file_bytes = 64;
  const std::string e = input_error([&] { load_trace(dir.file("big.csv"), small); });
  CHECK(contains(e, dir.file("big.csv")));
  CHECK(contains(e, "more than the limit of 64 bytes"));
  TraceReadOptions short_lines;
  short_lines.limits.max_line_bytes = 20;
  CHECK(contains(input_error([&] { load_trace(dir.file("big.csv"), short_lines); }),
                 dir.file("big.csv") + ":1: line longer than 20 bytes"));
}

TEST_CASE("validate_trace and save_trace refuse invalid traces") {
  ScratchDir dir;
  Trace t;
  CHECK(contains(input_error([&] { save_trace(t, dir.file("x.csv")); }), "no poses"));
  t.poses.resize(2);
  t.poses[1].t_s = 0.0;
  CHECK(contains(input_error([&] { validate_trace(t, "t"); }), "t pose 1"));
  t.poses[1].t_s = 1.0;
  t.poses[1].q = glm::dquat(2.0, 0.0, 0.0, 0.0);
  CHECK(contains(input_error([&] { validate_trace(t, "t"); }), "not unit"));
  t.poses[1].q = glm::dquat(1.0, 0.0, 0.0, 0.0);
  t.poses[0].pos_m.y = std::numeric_limits<double>::quiet_NaN();
  CHECK(contains(input_error([&] { validate_trace(t, "t"); }), "t pose 0"));
  t.poses[0].pos_m.y = 0.0;
  t.image_width = 0;
  CHECK(contains(input_error([&] { validate_trace(t, "t"); }), "image size"));
  t.image_width = 10;
  CHECK_NOTHROW(validate_trace(t, "t"));
  CHECK(contains(input_error([&] { save_trace(t, dir.file("no/such/dir.csv")); }), "cannot create"));
}
