// Every extension point's table, entry by entry (docs/architecture.md, "Extension points"): each
// registered throttle policy, scene, codec, disk preset and streaming system passes the same
// checks, so a new entry is tested by being registered; and every implementation file in a
// policy, codec or trace-format folder is in its table. (Trace format round trips:
// test_trace_formats.cpp.)
#include <doctest/doctest.h>

#include <fmt/format.h>

#include <bit>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>

#include "core/camera.h"
#include "cache/policy/i_replacement.h"
#include "core/error.h"
#include "sim/run/replay.h"
#include "sim/run/systems.h"
#include "sim/trace/trace_format.h"
#include "sim/trace/trace_gen.h"
#include "sim/view/scene.h"
#include "store_test_util.h"
#include "stream/exec/device_model.h"
#include "stream/store/i_codec.h"
#include "stream/throttle/i_throttle.h"
#include "test_util.h"
#include "view_test_util.h"

using namespace vtsim;

namespace {

// Names of the files `prefix`*.cpp in a source folder, without the prefix: what a table must list.
std::set<std::string> impl_files(const std::string& folder, const std::string& prefix) {
  std::set<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(std::string(VTSIM_SOURCE_DIR) + "/" + folder)) {
    const std::string f = e.path().filename().string();
    if (f.rfind(prefix, 0) == 0 && e.path().extension() == ".cpp") names.insert(f.substr(prefix.size(), f.size() - prefix.size() - 4));
  }
  return names;
}

template <class Entry>
std::set<std::string> registered(const Registry<Entry>& r) {
  std::set<std::string> names;
  for (const Entry& e : r.entries()) {
    CHECK_MESSAGE(!e.why.empty(), r.what() << " '" << e.name << "' has no why");
    names.insert(std::string(e.name));
  }
  return names;
}

// A pipeline that cannot keep up, in every signal a policy reads: a backlog that takes seconds
// at the service rate and does not drain, a pool wanted twice over and full.
ThrottleInput overloaded(int frame) {
  ThrottleInput in;
  in.frame = frame;
  in.frame_period_s = 1.0 / 60.0;
  in.num_levels = 8;
  in.finest_needed = 0;
  in.coarsest_clamp = 6;
  in.missing_bytes_by_level.assign(8, 4'000'000);  // 4 MB a level at 10 MB/s: 3.2 s of work
  in.service_Bps = 10e6;
  in.pool_occupancy = 1.0;
  in.pool_pressure = 2.0;
  in.pool_demand_by_level = {2000, 500, 128, 32, 8, 2, 1, 1};
  in.pool_slots = 128;
  return in;
}

// The same pipeline with nothing left to do.
ThrottleInput idle(int frame) {
  ThrottleInput in = overloaded(frame);
  in.missing_bytes_by_level.assign(8, 0);
  in.pool_occupancy = 0.1;
  in.pool_pressure = 0.1;
  in.pool_demand_by_level = {8, 2, 1, 1, 1, 1, 1, 1};
  return in;
}

}  // namespace

TEST_CASE("throttle policies: every file in stream/throttle/impl is registered, every entry has a why") {
  CHECK(impl_files("src/stream/throttle/impl", "throttle_") == registered(throttle_policies()));
}

TEST_CASE("throttle policies, each: engages under load, relaxes when the load is gone, stays within its bounds") {
  for (const ThrottlePolicyInfo& info : throttle_policies().entries()) {
    CAPTURE(std::string(info.name));
    ThrottleParams p;
    p.policy = std::string(info.name);
    const auto policy = make_throttle_policy(p);
    REQUIRE(policy);
    CHECK(std::string(policy->name()) == info.name);
    const auto within = [&](const ThrottleDecision& d, const ThrottleInput& in) {
      CHECK(d.clamp >= 0);
      CHECK(d.clamp <= in.coarsest_clamp);  // never coarser than "the pyramid only"
      CHECK(d.bias >= 0.0);
      CHECK(d.bias <= p.max_bias);
      CHECK(d.sample_bias >= 0.0);
      CHECK(d.sample_bias <= p.max_bias);
    };
    bool engaged = false;
    int f = 0;
    for (; f < 120; ++f) {
      const ThrottleInput in = overloaded(f);
      const ThrottleDecision d = policy->update(in);
      within(d, in);
      engaged = engaged || d.clamp > 0 || d.bias > 0.0;
    }
    // "none" is the baseline that never throttles; every other policy must act on this load.
    CHECK(engaged == (info.name != "none"));
    ThrottleDecision d;
    const int load_gone = f;
    for (; f < load_gone + 5000; ++f) {
      const ThrottleInput in = idle(f);
      d = policy->update(in);
      within(d, in);
      if (d.clamp == 0 && d.bias == 0.0 && d.sample_bias == 0.0) break;
    }
    CHECK(d.clamp == 0);
    CHECK(d.bias == 0.0);
    CHECK(d.sample_bias == 0.0);
  }
}

TEST_CASE("throttle none: never clamps, never biases, whatever the load") {
  ThrottleParams p;
  p.policy = "none";
  const auto none = make_throttle_policy(p);
  for (int f = 0; f < 300; ++f) {
    const ThrottleDecision d = none->update(f % 2 ? overloaded(f) : idle(f));
    CHECK(d.clamp == 0);
    CHECK(d.bias == 0.0);
    CHECK(d.sample_bias == 0.0);
    CHECK(d.reason.empty());
  }
}

TEST_CASE("throttle deadline: clamps to the finest level whose backlog fits the deadline, after relax_frames of outrun, and relaxes after relax_frames caught up") {
  ThrottleParams p;  // deadline 250 ms, relax factor 0.5, 15 frames, drain horizon 1 s
  p.policy = "deadline";
  const auto deadline = make_throttle_policy(p);
  ThrottleInput in;
  in.frame_period_s = 1.0 / 60.0;
  in.num_levels = 4;
  in.coarsest_clamp = 3;
  in.service_Bps = 1e6;
  // Coarse before fine: level l completes after every coarser byte. eta(0) = 0.55 s, eta(1) =
  // 0.15 s, eta(2) = 0.05 s: level 1 is the finest that fits 250 ms.
  in.missing_bytes_by_level = {400'000, 100'000, 50'000, 0};
  int f = 0;
  for (; f < 15; ++f) {
    in.frame = f;
    // A backlog that neither grows nor drains is the camera outrunning the updates, but only once
    // its rate has been measured over relax_frames frames.
    CHECK(deadline->update(in).clamp == 0);
  }
  in.frame = f++;
  const ThrottleDecision engaged = deadline->update(in);
  CHECK(engaged.clamp == 1);
  CHECK(test::contains(engaged.reason, "engage: backlog from level 0 needs 550 ms > deadline 250 ms"));
  for (int k = 0; k < 100; ++k, ++f) {  // it holds while the load stays
    in.frame = f;
    CHECK(deadline->update(in).clamp == 1);
  }
  in.missing_bytes_by_level = {0, 0, 0, 0};  // caught up
  for (int k = 0; k < 14; ++k, ++f) {
    in.frame = f;
    CHECK(deadline->update(in).clamp == 1);
  }
  in.frame = f++;
  const ThrottleDecision relaxed = deadline->update(in);
  CHECK(relaxed.clamp == 0);
  CHECK(test::contains(relaxed.reason, "relax:"));
  // A large backlog that drains fast enough (the first fill) does not clamp.
  const auto fresh = make_throttle_policy(p);
  for (int k = 0; k < 200; ++k) {
    in.frame = k;
    const std::uint64_t left = k < 100 ? static_cast<std::uint64_t>(900'000 - 9'000 * k) : 0;
    in.missing_bytes_by_level = {left, 0, 0, 0};
    CHECK(fresh->update(in).clamp == 0);
  }
}

TEST_CASE("scenes: every entry has a why, and an unknown name lists them and suggests one") {
  CHECK(registered(scenes()).size() == scenes().entries().size());
  const std::string e = [] {
    try {
      find_scene("plain");
    } catch (const InputError& err) {
      return std::string(err.what());
    }
    return std::string();
  }();
  CHECK(test::contains(e, "unknown scene 'plain' (one of: " + scenes().names() + "; did you mean 'plane'?)"));
}

// A known view gives a known feedback: per scene a fixed camera and the digest of every sample
// (texel, LOD bits, pixel) and counter. A renderer change that moves any sample changes it; a
// scene added to the table without a case here fails.
TEST_CASE("scenes, each: a known view renders a known feedback, per sample and as spans") {
  const std::string obj = test::temp_path("ground.obj");
  {  // a 200 m ground quad whose UVs span the texture, and a wall across it
    std::ofstream out(obj);
    out << "v 0 0 0\nv 200 0 0\nv 200 200 0\nv 0 200 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n"
           "v 60 100 0\nv 140 100 0\nv 140 100 20\nv 60 100 20\nvt 0.1 0.1\nvt 0.2 0.1\nvt 0.2 0.2\nvt 0.1 0.2\n"
           "f 5/5 6/6 7/7 8/8\n";
  }
  struct Case {
    Pose pose;
    std::uint64_t samples;
    std::uint64_t digest;
  };
  // A new scene adds its line: a camera that sees it, then the count and digest this test prints
  // for it. Regenerate a digest only with a change that explains why the scene renders differently.
  const std::map<std::string, Case> cases = {
      {"plane", {pose_from_angles({4096, 4096, 1.7}, 30, -15), 23760, 0xff392276f8921854ull}},
      {"heightfield", {pose_from_angles({2000, 3000, 250}, 60, -10), 20012, 0x4a1d3db85f3d96d1ull}},
      {"town", {pose_from_angles({30, 8, 1.7}, 0, 0), 21369, 0xe2f2091b4f3be845ull}},
      {"mesh", {pose_from_angles({100, 20, 1.7}, 90, -10), 24467, 0x2417026dc9c7a39full}},
  };
  for (const SceneInfo& info : scenes().entries()) {
    CAPTURE(std::string(info.name));
    const auto it = cases.find(std::string(info.name));
    // A scene without a case renders at the plane's camera, and the failure says what to add.
    const Case known = it != cases.end() ? it->second : Case{cases.at("plane").pose, 0, 0};
    SceneConfig cfg;
    cfg.kind = std::string(info.name);
    if (info.name == "mesh") cfg.size_x_m = cfg.size_y_m = 200.0, cfg.file = obj;
    if (info.file_required) {
      SceneConfig none = cfg;
      none.file.clear();
      CHECK_THROWS_AS(make_scene(none), InputError);
    }
    const auto scene = make_scene(cfg);
    const Camera cam = make_camera(known.pose, 1920, 1080);
    ViewParams vp;  // divisor 8
    ViewBuffer vb;
    scene->render(cam, vp, vb);
    std::uint64_t h = 0xcbf29ce484222325ull;  // FNV-1a over every sample and counter
    const auto mix = [&h](std::uint64_t v) {
      for (int b = 0; b < 8; ++b) h = (h ^ ((v >> (8 * b)) & 0xff)) * 0x100000001b3ull;
    };
    for (const ViewSample& s : vb.samples) {
      mix(static_cast<std::uint64_t>(s.u));
      mix(static_cast<std::uint64_t>(s.v));
      mix(std::bit_cast<std::uint32_t>(s.lod));
      mix(s.pixel);
    }
    for (std::uint64_t c : {vb.counters.sky, vb.counters.clipped, vb.counters.backfacing, vb.counters.outside_texture,
                            vb.counters.untextured})
      mix(c);
    CHECK_MESSAGE(it != cases.end(), "scene '" << info.name << "' has no known view in this test: give it a camera that "
                                                "sees it (here the plane's: " << vb.samples.size() << " samples, digest "
                                                << fmt::format("{:#x}", h) << ")");
    CHECK(vb.samples.size() == known.samples);
    CHECK(h == known.digest);
    // The span form is the same frame (view_spans.h): its expansion gives every sample back.
    SpanBuffer sb;
    scene->render_spans(cam, vp, sb);
    materialise_samples(sb);
    REQUIRE(sb.view.samples.size() == vb.samples.size());
    for (std::size_t i = 0; i < vb.samples.size(); ++i) REQUIRE(test::same_sample(sb.view.samples[i], vb.samples[i]));
  }
  std::filesystem::remove(obj);
}

TEST_CASE("trace formats: every file in sim/trace/impl is registered (format_common.cpp is their shared code)") {
  std::set<std::string> files = impl_files("src/sim/trace/impl", "format_");
  files.erase("common");
  CHECK(files == registered(trace_formats()));
}

TEST_CASE("replacement policies: every file in cache/policy/impl is registered, every entry has a why") {
  CHECK(impl_files("src/cache/policy/impl", "policy_") == registered(replacement_policies()));
}

TEST_CASE("codecs: every file in stream/store/impl is registered, every entry has a why") {
  std::set<std::string> files = impl_files("src/stream/store/impl", "codec_");
  CHECK(files == registered(codecs()));
}

TEST_CASE("codecs, each: its name parses, it round-trips what it supports (exactly when lossless), refuses a cut payload") {
  for (const CodecInfo& info : codecs().entries()) {
    CAPTURE(std::string(info.name));
    const CodecSpec spec = parse_codec_spec(info.name, "--codec");
    CHECK(spec.id == info.id);
    CHECK(spec.param == info.default_param);
    CHECK(codec_name(info.id) == info.name);
    const auto codec = make_codec(info.id, info.default_param);
    CHECK(codec->id() == info.id);
    for (int c = 1; c <= 4; ++c) {
      if (!codec->supports_channels(c)) continue;
      CAPTURE(c);
      const Image8 img = test::make_image(64, 48, static_cast<std::uint32_t>(c), 11);
      const auto bytes = codec->encode(img.texels.data(), 64, 48, c);
      std::vector<std::uint8_t> out(img.texels.size(), 0);
      decoder_for(info.id).decode(bytes.data(), bytes.size(), 64, 48, c, out.data());
      if (codec->lossless()) {
        CHECK(out == img.texels);
      } else {
        double se = 0;
        for (std::size_t i = 0; i < out.size(); ++i) se += (out[i] - img.texels[i]) * double(out[i] - img.texels[i]);
        CHECK(10.0 * std::log10(255.0 * 255.0 * static_cast<double>(out.size()) / std::max(se, 1e-9)) > 30.0);
      }
      if (bytes.size() > 1) {  // a payload cut short never decodes silently
        CHECK_THROWS_AS(decoder_for(info.id).decode(bytes.data(), bytes.size() / 2, 64, 48, c, out.data()), CodecError);
      }
    }
  }
  CHECK_THROWS_AS(parse_codec_spec("zstdd", "--codec"), InputError);
}

TEST_CASE("disk presets, each: a why, a device the simulated clock can serve, and a model with overrides") {
  for (const DevicePreset& p : disk_presets().entries()) {
    CAPTURE(std::string(p.name));
    CHECK(!p.why.empty());
    CHECK(p.disk.latency_us >= 0.0);
    CHECK(p.disk.bandwidth_MBps >= 0.0);
    CHECK(p.disk.channels >= 0);
    CHECK(disk_throughput_Bps(p.disk, 128.0 * 128 * 4) > 0.0);
    DiskConfig c;
    c.preset = std::string(p.name);
    const DiskModel m = disk_model(c);
    CHECK(m.latency_us == p.disk.latency_us);
    CHECK(m.channels == p.disk.channels);
    c.bandwidth_MBps = 42.0;
    CHECK(disk_model(c).bandwidth_MBps == 42.0);
    CHECK(disk_model(c).latency_us == p.disk.latency_us);
  }
  DiskConfig bad;
  bad.preset = "nvm";
  std::string message;
  try {
    disk_model(bad);
  } catch (const std::invalid_argument& e) {
    message = e.what();
  }
  CHECK(message == "unknown disk preset 'nvm' (one of: hdd, sata_ssd, nvme, optical, unconstrained; did you mean 'nvme'?)");
}

TEST_CASE("streaming systems, each: a short replay runs, uploads, measures and is the same twice") {
  TraceGenParams g = default_gen_params("walk");
  g.duration_s = 2.0;
  g.start_m = {30.0, 8.0};  // along the town's first street
  const Trace walk = generate_trace(g);
  for (const SystemInfo& info : streaming_systems().entries()) {
    CAPTURE(std::string(info.name));
    CHECK(!info.why.empty());
    const ReplayConfig cfg =
        load_replay_config("", {"scene.kind=town", "texture.border=0", "vt.pool_pages=256", "view.render_threads=0"},
                           std::string(info.name));
    const auto scene = make_scene_from_config(cfg);
    CHECK(info.store_levels(cfg) >= 1);
    CHECK(info.store_levels(cfg) <= mip_level_count(scene->texture()));
    const ReplayResult a = run_replay(cfg, walk, *scene);
    const ReplayResult b = run_replay(cfg, walk, *scene);
    CHECK(a.summary["system"] == info.name);
    CHECK(a.summary["bandwidth"]["uploads"].get<std::uint64_t>() > 0);
    CHECK(a.summary.contains(std::string(info.name)));
    CHECK(a.metrics.frames() == b.metrics.frames());
    nlohmann::json sa = a.summary, sb = b.summary;
    sa.erase("run");
    sb.erase("run");
    CHECK(sa == sb);
  }
}
