// Whole-replay behaviour of the clipmap in the simulated clock: the closed-form bandwidth, a static
// camera, a camera far from the origin, determinism, the upload budget, bad configs.
#include <doctest/doctest.h>

#include <atomic>
#include <cmath>
#include <fstream>

#include "core/error.h"
#include "core/camera.h"
#include "sim/run/replay.h"
#include "sim/view/scene.h"
#include "sim/trace/trace_gen.h"
#include "stream/system/i_system.h"
#include "replay_test_util.h"
#include "trace_test_util.h"

using namespace vtsim;

namespace {

// Unconstrained devices, no throttle: every needed tile is resident in the frame that needs it.
std::vector<std::string> unconstrained() {
  return {"disk.preset=unconstrained", "upload.tiles_per_frame=-1", "upload.link_MBps=0",
          "throttle.policy=none", "io.max_in_flight=1000000"};
}

ReplayResult replay(const Trace& t, std::vector<std::string> sets) {
  const ReplayConfig cfg = load_replay_config("", sets);
  auto scene = make_scene_from_config(cfg);
  return run_replay(cfg, t, *scene);
}

// A straight walk at 1.7 m looking 30° down (so level 0 is always wanted), exact positions:
// x = x0 + dx·f/fps (and y likewise), computed from the frame index.
Trace straight(double x0, double y0, double dx_mps, double dy_mps, double seconds, double yaw_deg) {
  Trace t;
  t.name = "straight";
  const int frames = static_cast<int>(seconds * 60.0);
  for (int f = 0; f <= frames; ++f) {
    const double s = f / 60.0;
    Pose p = pose_from_angles({x0 + dx_mps * s, y0 + dy_mps * s, 1.7}, yaw_deg, -30.0);
    p.t_s = s;
    t.poses.push_back(p);
  }
  return t;
}

// Recentres of one axis of a stack level (docs/clipmap.md): the first placement puts the centre
// tile at c0 = floor(p0 / T); with threshold thr texels < T the window then steps one tile each
// time the level texel p reaches (c + 1)·T + thr, so after a monotone move to p1 it has stepped
// max(0, floor((p1 - thr) / T) - c0) times.
std::int64_t steps(std::int64_t p0, std::int64_t p1, std::int64_t T, std::int64_t thr) {
  const std::int64_t c0 = p0 / T;
  const std::int64_t s = (p1 - thr) / T - c0;
  return s > 0 ? s : 0;
}

std::int64_t texel(double x_m) { return static_cast<std::int64_t>(std::floor(x_m * 128.0)); }

}  // namespace

TEST_CASE("closed form: a straight axis-aligned walk reads n tiles per window step per stack level, exactly") {
  // 65536² texels (512 m at 128 texels/m), N = 1024, T = 128: 6 stack levels as in Yao 2007 §5-1.
  auto sets = unconstrained();
  sets.insert(sets.end(), {"texture.width=65536", "texture.height=65536"});
  const Trace t = straight(256.0, 256.0, 1.5, 0.0, 20.0, 0.0);
  const ReplayResult r = replay(t, sets);
  for (const auto& row : r.metrics.frames()) REQUIRE(row.finest_needed == 0);
  // Initial fill: 6 stack windows of 8×8 tiles + the pyramid (1024², 512², 256², 128², then 7
  // levels of one tile each): 384 + 64 + 16 + 4 + 1 + 7 = 476 tiles.
  std::int64_t tiles = 476;
  const std::int64_t g0 = texel(256.0), g1 = texel(t.poses.back().pos_m.x);
  for (int l = 0; l < 6; ++l) tiles += 8 * steps(g0 >> l, g1 >> l, 128, 64);
  CHECK(tiles > 476);
  CHECK(r.summary["bandwidth"]["disk_read_bytes"].get<std::int64_t>() == tiles * 65536);
  CHECK(r.summary["bandwidth"]["upload_bytes"].get<std::int64_t>() == tiles * 65536);
  CHECK(r.summary["popin"]["blurry_fraction_mean"].get<double>() >= 0.0);
}

TEST_CASE("closed form: an exact 45° walk steps both axes in the same frame: 2n - 1 tiles a step") {
  auto sets = unconstrained();
  sets.insert(sets.end(), {"texture.width=65536", "texture.height=65536"});
  const double v = 1.5 / std::sqrt(2.0);
  const Trace t = straight(256.0, 256.0, v, v, 20.0, 45.0);
  const ReplayResult r = replay(t, sets);
  std::int64_t tiles = 476;
  const std::int64_t g0 = texel(256.0), g1 = texel(t.poses.back().pos_m.x);
  REQUIRE(g1 == texel(t.poses.back().pos_m.y));
  for (int l = 0; l < 6; ++l) tiles += (2 * 8 - 1) * steps(g0 >> l, g1 >> l, 128, 64);
  CHECK(r.summary["bandwidth"]["disk_read_bytes"].get<std::int64_t>() == tiles * 65536);
}

TEST_CASE("a static camera costs no IO and no uploads after warm-up") {
  TraceGenParams g = default_gen_params("static");
  g.duration_s = 10.0;
  const ReplayResult r = replay(generate_trace(g), {});  // default devices: NVMe, 16 tiles/frame
  const auto& frames = r.metrics.frames();
  int warm = 0;
  while (warm < static_cast<int>(frames.size()) && (frames[static_cast<std::size_t>(warm)].needs > 0 ||
                                                     frames[static_cast<std::size_t>(warm)].live_requests > 0))
    ++warm;
  REQUIRE(warm < 300);
  for (std::size_t f = static_cast<std::size_t>(warm); f < frames.size(); ++f) {
    CHECK(frames[f].disk_bytes == 0);
    CHECK(frames[f].uploads == 0);
    CHECK(frames[f].blurry == frames.back().blurry);
  }
}

TEST_CASE("a camera 10^7 m from the origin behaves exactly like one at the origin") {
  TraceGenParams g = default_gen_params("walk");
  g.duration_s = 5.0;
  Trace near = generate_trace(g);
  g.start_m += glm::dvec2(1.0e7, 1.0e7);
  Trace far = generate_trace(g);
  ReplayResult a = replay(near, {});
  ReplayResult b = replay(far, {"texture.origin_x_m=10000000", "texture.origin_y_m=10000000"});
  a.summary.erase("run");
  b.summary.erase("run");
  a.summary["trace"].erase("name");
  b.summary["trace"].erase("name");
  for (const char* k : {"texture.origin_x_m", "texture.origin_y_m"}) {  // the config keys that moved
    a.summary["config"].erase(k);
    b.summary["config"].erase(k);
  }
  CHECK(a.summary.dump() == b.summary.dump());
}

TEST_CASE("determinism: two runs give the same summary and frames, bit for bit") {
  TraceGenParams g = default_gen_params("drive");
  g.duration_s = 5.0;
  const Trace t = generate_trace(g);
  const std::vector<std::string> sets = {"disk.preset=hdd", "io.fault_rate=0.05", "decode.throughput_MBps=300"};
  const ReplayResult a = replay(t, sets), b = replay(t, sets);
  test::check_same_results(a, b);
  CHECK(a.summary["faults"]["faults"].get<int>() > 0);
}

namespace {

// A scene that counts its renders (a decorator: the inner scene does the work).
class CountingScene final : public IScene {
 public:
  explicit CountingScene(const IScene& s) : s_(s) {}
  TextureExtent texture() const override { return s_.texture(); }
  void render(const Camera& c, const ViewParams& p, ViewBuffer& out) const override {
    ++renders;
    s_.render(c, p, out);
  }
  void render_spans(const Camera& c, const ViewParams& p, SpanBuffer& out) const override {
    ++renders;
    s_.render_spans(c, p, out);
  }
  void render_pixels(const SpanBuffer& sb, std::uint32_t pixel, std::uint32_t count, std::vector<ViewSample>& out) const override {
    s_.render_pixels(sb, pixel, count, out);
  }
  mutable std::atomic<int> renders{0};  // render-ahead workers render too

 private:
  const IScene& s_;
};

}  // namespace

TEST_CASE("paced (the real clock's loop): the first views are rendered before frame 0, and nothing else changes") {
  TraceGenParams g = default_gen_params("walk");
  g.duration_s = 1.0;
  const Trace t = generate_trace(g);
  for (const char* system : {"clipmap", "vt"})
  for (const int threads : {0, 2}) {
    CAPTURE(system);
    CAPTURE(threads);
    const ReplayConfig cfg = load_replay_config("", {std::string("run.system=") + system,
                                                     "view.render_threads=" + std::to_string(threads)});
    auto inner = make_scene_from_config(cfg);
    CountingScene scene(*inner);
    const ReplayResult plain = run_replay(cfg, t, scene);
    const int plain_renders = scene.renders;
    CHECK(plain_renders == static_cast<int>(plain.metrics.frames().size()));  // a walk: every pose differs
    scene.renders = 0;
    ReplayEnv env;
    int before_frame0 = -1;
    env.pace = [&](int f, Ticks target) {
      if (f == 0) before_frame0 = scene.renders;
      return target;
    };
    const ReplayResult paced = run_replay(cfg, t, scene, env);
    if (threads == 0) {
      CHECK(before_frame0 == 1);  // one extra render, of the first view
      CHECK(scene.renders == plain_renders + 1);
    } else {
      CHECK(before_frame0 >= threads);  // the workers' first frames, which the loop then takes
      CHECK(scene.renders == plain_renders);
    }
    test::check_same_results(plain, paced);
  }
}

TEST_CASE("the upload budget is never exceeded in a replay") {
  TraceGenParams g = default_gen_params("drive");
  g.duration_s = 4.0;
  const ReplayResult r = replay(generate_trace(g), {"upload.tiles_per_frame=5", "upload.bytes_per_frame=200000"});
  std::uint64_t total = 0;
  for (const auto& row : r.metrics.frames()) {
    CHECK(row.uploads <= 5);
    CHECK(row.upload_bytes <= 200000);
    total += row.uploads;
  }
  CHECK(total > 100);
}

TEST_CASE("the throttle engages when the camera outruns the disk and relaxes when it stops") {
  // Drive for 8 s on an HDD, then stand still for 8 s.
  TraceGenParams g = default_gen_params("drive");
  g.duration_s = 8.0;
  Trace t = generate_trace(g);
  test::hold_last_pose(t, 480);
  const ReplayResult r = replay(t, {"disk.preset=hdd"});
  const auto& changes = r.metrics.throttle_changes();
  REQUIRE(changes.size() >= 2);
  CHECK(changes.front().to > changes.front().from);  // engage while driving
  CHECK(changes.front().t_s < 8.0);
  CHECK(changes.back().to == 0);                     // fully relaxed once standing
  CHECK(changes.back().t_s > 8.0);
  CHECK(r.metrics.frames().back().clamp == 0);
}

TEST_CASE("config files: nesting, long keys and NUL characters are refused at their line, quickly") {
  const std::string path = std::string(VTSIM_TEST_DATA) + "/../../build-test-config-limits.toml";
  const auto error_of = [&](const std::string& text) {
    test::write_file(path, text);
    try {
      load_replay_config(path, {});
      return std::string();
    } catch (const InputError& e) {
      return std::string(e.what());
    }
  };
  // Each dot opens a table one level deeper; 5,000 overflowed the stack (flatten, toml++'s
  // destructor). 16 dots are the limit: in keys, table headers and inline tables alike.
  const auto dots = [](int n) {
    std::string k = "a";
    for (int i = 0; i < n; ++i) k += ".a";
    return k;
  };
  CHECK(test::contains(error_of(dots(16) + " = 1\n"), "unknown config key"));
  CHECK(test::contains(error_of("# comment\n" + dots(17) + " = 1\n"), ":2: a key or table name nested more than 16 levels"));
  CHECK(test::contains(error_of(dots(5000) + " = 1\n"), ":1: a key or table name nested more than 16 levels"));
  CHECK(test::contains(error_of("[" + dots(20) + "]\nx = 1\n"), ":1: a key or table name nested"));
  CHECK(test::contains(error_of("x = { " + dots(20) + " = 1 }\n"), ":1: a key or table name nested"));
  CHECK(test::contains(error_of("x = [1, { y = { " + dots(20) + " = 2 } }]\n"), ":1: a key or table name nested"));
  CHECK(test::contains(error_of("x = " + std::string(17, '[') + std::string(17, ']') + "\n"), ":1: a key or table name nested"));
  CHECK(test::contains(error_of("a.b = { c.d = { e = { f = [ [ [ [ [ [ [ [ [ [ [ [1] ] ] ] ] ] ] ] ] ] ] ] } } }\n"),
                       ":1: a key or table name nested"));
  // Levels close again: an empty inline table, then arrays on later lines.
  CHECK(test::contains(error_of("x = {}\ny = [[1], [2]]\n" + dots(16) + " = 1\n"), "unsupported value type"));
  // Dots in values, strings, comments and quoted keys are not nesting.
  const std::string many = "1.2.3.4.5.6.7.8.9.10.11.12.13.14.15.16.17.18";
  CHECK(test::contains(error_of("[run]\nnote = \"" + many + "\"\n"), "unknown config key 'run.note'"));
  CHECK(test::contains(error_of("[run]\nnote = \"\"\"\n" + many + "\n\"\"\"\n"), "unknown config key 'run.note'"));
  CHECK(test::contains(error_of("[run]\nnote = '''\n" + many + "'''\n"), "unknown config key 'run.note'"));
  CHECK(test::contains(error_of("\"" + many + "\" = 1\n"), "unknown config key"));
  CHECK(error_of("[run]\nfps = 60.5 # " + many + "\n").empty());
  // A megabyte key: refused at once (no edit distance over it), quoted by its first 100 characters.
  const std::string e = error_of(std::string(1 << 20, 'k') + " = 1\n");
  CHECK(test::contains(e, ":1: unknown config key 'kkkk"));
  CHECK(test::contains(e, "…' (1048576 characters)"));
  CHECK(e.size() < 300);
  // A NUL inside a string would cut a path short.
  CHECK(test::contains(error_of("[scene]\nfile = \"a.obj\\u0000.txt\"\n"), ":2: field 'scene.file': a string with a NUL"));
  std::remove(path.c_str());
}

TEST_CASE("impossible configs are rejected with the field's name") {
  auto rejects = [](std::vector<std::string> sets, const std::string& field) {
    try {
      load_replay_config("", sets);
      FAIL("accepted: " << field);
    } catch (const InputError& e) {
      CHECK_MESSAGE(std::string(e.what()).find(field) != std::string::npos, e.what());
    }
  };
  rejects({"clipmap.clipsize=1000"}, "clipmap.clipsize");           // not a multiple of the tile
  rejects({"upload.tiles_per_frame=0"}, "upload.tiles_per_frame");  // zero budget
  rejects({"upload.bytes_per_frame=0"}, "upload.bytes_per_frame");
  rejects({"upload.bytes_per_frame=1000"}, "upload.bytes_per_frame");  // smaller than a tile
  rejects({"ram.capacity_MiB=0.01"}, "ram.capacity_MiB");           // cache smaller than one tile
  rejects({"clipmap.clipsiz=1024"}, "clipmap.clipsiz");             // unknown key
  rejects({"disk.preset=floppy"}, "disk.preset");
  rejects({"texture.layers=albedo:rgb9"}, "texture.layers");
  rejects({"view.divisor=-3"}, "view.divisor");
  rejects({"throttle.policy=magic"}, "throttle.policy");
  rejects({"run.fps=abc"}, "run.fps");
  // Out-of-range numbers are numbers: the field's own check names them.
  rejects({"run.fps=1e-320"}, "below 0.01 Hz");  // a subnormal rate: frame 0 only
  rejects({"run.fps=1e400"}, "finite");
  rejects({"run.fps="}, "expected a number");
  CHECK_NOTHROW(load_replay_config("", {"run.fps=0.01"}));
  // Sizes and rates that would make the simulation endless or overflow its nanosecond clock.
  rejects({"texture.tile_size=4"}, "texture.tile_size");
  rejects({"clipmap.clipsize=65536"}, "clipmap.clipsize");  // 512 tiles a side
  rejects({"disk.bandwidth_MBps=1e-300"}, "disk.bandwidth_MBps");
  rejects({"decode.throughput_MBps=1e-4"}, "decode.throughput_MBps");
  rejects({"upload.link_MBps=1e-10"}, "upload.link_MBps");
  CHECK_NOTHROW(load_replay_config("", {"disk.bandwidth_MBps=0.001", "clipmap.clipsize=32768"}));

  const std::string path = std::string(VTSIM_TEST_DATA) + "/../../build-test-config.toml";
  {
    std::ofstream f(path);
    f << "[clipmap]\nclipsize = 1024\n\n[upload]\ntiles_per_frame = 8\nbogus = 3\n";
  }
  try {
    load_replay_config(path, {});
    FAIL("accepted an unknown key");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).find("build-test-config.toml:6") != std::string::npos);
    CHECK(std::string(e.what()).find("upload.bogus") != std::string::npos);
  }
  std::remove(path.c_str());
}
