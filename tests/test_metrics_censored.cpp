// Metrics that do not reward starving (docs/metrics.md): latency counts every request, served or
// censored (Kaplan–Meier); a trace without events has no time to sharp; metrics.warmup_s leaves
// the start-up fill out of the steady-state figures and reports it on its own.
#include <doctest/doctest.h>

#include <string>
#include <vector>

#include "sim/compare/compare.h"
#include "sim/run/metrics.h"
#include "sim/run/replay.h"
#include "sim/trace/trace_gen.h"
#include "sim/trace/trace_io.h"
#include "sim/view/scene.h"

using namespace vtsim;

namespace {

ReplayResult censored_replay(const std::vector<std::string>& sets, const std::string& gen = "walk duration_s=4") {
  const ReplayConfig cfg = load_replay_config("", sets);
  const Trace t = generate_trace(parse_gen_line(gen, "test"));
  auto scene = make_scene_from_config(cfg);
  return run_replay(cfg, t, *scene);
}

}  // namespace

TEST_CASE("metrics: Kaplan-Meier quantiles count censored times, and equal nearest-rank without censoring") {
  const std::vector<double> qs = {0.5, 0.95, 0.99};
  // Without censoring: the nearest-rank percentiles.
  const std::vector<double> ev = {4, 1, 3, 2, 5, 6, 7, 8, 9, 10};
  const auto plain = km_quantiles(ev, {}, qs);
  const Percentiles p = percentiles(ev);
  CHECK(plain[0] == p.p50);
  CHECK(plain[1] == p.p95);
  CHECK(plain[2] == p.p99);
  // Events at 1 and 3, two censored at 2: S(1) = 3/4, then one at risk at 3: S(3) = 0.
  auto km = km_quantiles({1, 3}, {2, 2}, qs);
  CHECK(km[0] == 3.0);
  CHECK(km[1] == 3.0);
  // One event at 1 of four, the rest censored later: the median is never reached (null), not 1.
  km = km_quantiles({1}, {5, 5, 5}, qs);
  CHECK_FALSE(km[0].has_value());
  // A censoring at the same time as an event is still at risk at it (events first).
  km = km_quantiles({2, 4}, {2}, {0.3});
  CHECK(km[0] == 2.0);  // S(2) = 1 - 1/3
}

TEST_CASE("metrics: latency counts every demand request: served plus censored is cache.requests, on a starved run") {
  for (const char* system : {"clipmap", "vt"}) {
    CAPTURE(system);
    // HDD and a small RAM, one tile per frame: most requests are cancelled or still open at the end.
    const ReplayResult r = censored_replay({std::string("run.system=") + system, "disk.preset=hdd", "upload.tiles_per_frame=1",
                                            "view.divisor=16", "ram.capacity_MiB=16"});
    const auto& l = r.summary["latency_ms"];
    const auto requests = r.summary["cache"]["requests"].get<std::uint64_t>();
    CHECK(l["requests"].get<std::uint64_t>() == requests);
    CHECK(l["tiles"].get<std::uint64_t>() + l["censored"]["count"].get<std::uint64_t>() == requests);
    CHECK(l["censored"]["count"].get<std::uint64_t>() ==
          l["censored"]["cancelled"].get<std::uint64_t>() + l["censored"]["failed"].get<std::uint64_t>() +
              l["censored"]["open_at_end"].get<std::uint64_t>() + l["censored"]["stale"].get<std::uint64_t>());
    CHECK(l["censored"]["count"].get<std::uint64_t>() > 0);
    CHECK(l["served_fraction"].get<double>() ==
          static_cast<double>(l["tiles"].get<std::uint64_t>()) / static_cast<double>(requests));
    CHECK(l["served_fraction"].get<double>() < 1.0);
    CHECK(l["censored"]["wait_ms"]["count"].get<std::uint64_t>() == l["censored"]["count"].get<std::uint64_t>());
    // Every served tile's latency is an observed event of the Kaplan–Meier curve: its quantiles
    // are at least the served ones (censored requests only hold the curve up).
    if (l["km"]["p50"].is_number()) CHECK(l["km"]["p50"].get<double>() >= l["p50"].get<double>());
  }
  // Nothing starves: everything needed is served, or open at the end.
  const ReplayResult r = censored_replay({"run.system=clipmap", "view.divisor=16"});
  const auto& l = r.summary["latency_ms"];
  CHECK(l["tiles"].get<std::uint64_t>() + l["censored"]["count"].get<std::uint64_t>() ==
        r.summary["cache"]["requests"].get<std::uint64_t>());
}

TEST_CASE("metrics: a trace without a cut or fast turn has no time to sharp (null, not 0)") {
  const ReplayResult r = censored_replay({"view.divisor=16"}, "walk duration_s=2");
  const auto& tts = r.summary["popin"]["time_to_sharp_s"];
  CHECK(tts["events"] == 0);
  CHECK(tts["mean"].is_null());
  CHECK(tts["max"].is_null());
}

TEST_CASE("metrics: metrics.warmup_s leaves the start-up fill out and reports it in startup, and 0 changes nothing") {
  const std::vector<std::string> base = {"view.divisor=16", "upload.tiles_per_frame=8"};
  ReplayResult zero = censored_replay(base);
  std::vector<std::string> with0 = base;
  with0.push_back("metrics.warmup_s=0");
  ReplayResult zero2 = censored_replay(with0);
  zero.summary.erase("run");
  zero2.summary.erase("run");
  CHECK(zero.summary.dump() == zero2.summary.dump());
  CHECK(zero.summary["startup"]["frames"] == 0);
  CHECK(zero.summary["startup"]["tiles"] == 0);
  // The first sharp frame and the tiles before it, from the frames themselves.
  // Sharp: within metrics.sharp_margin (0.01) of the median blurry fraction of the run.
  const auto& frames = zero.metrics.frames();
  std::vector<double> bf;
  for (const FrameRow& f : frames)
    if (f.measured && f.samples > 0) bf.push_back(static_cast<double>(f.blurry) / f.samples);
  const double sharp = percentiles(bf).p50 + 0.01;
  std::size_t tiles = 0;
  double first_sharp = -1;
  for (const FrameRow& f : frames) {
    tiles += f.uploads;
    if (f.measured && f.samples > 0 && static_cast<double>(f.blurry) / f.samples <= sharp) {
      first_sharp = f.t_s;
      break;
    }
  }
  REQUIRE(first_sharp > 0);
  CHECK(zero.summary["startup"]["first_sharp_s"].get<double>() == first_sharp);
  CHECK(zero.summary["startup"]["tiles_to_first_sharp"].get<std::size_t>() == tiles);

  std::vector<std::string> with1 = base;
  with1.push_back("metrics.warmup_s=1");
  const ReplayResult warm = censored_replay(with1);
  const auto& su = warm.summary["startup"];
  std::size_t warm_frames = 0, warm_tiles = 0, steady_measured = 0;
  for (const FrameRow& f : warm.metrics.frames()) {
    if (f.t_s < 1.0) ++warm_frames, warm_tiles += f.uploads;
    else steady_measured += f.measured;
  }
  CHECK(warm_frames == 60);
  CHECK(su["frames"] == warm_frames);
  CHECK(su["tiles"] == warm_tiles);
  CHECK(su["warmup_s"] == 1.0);
  CHECK(warm.summary["popin"]["measured_frames"] == steady_measured);
  // Latency: only requests first needed at or after 1 s.
  std::size_t steady_tiles = 0;
  for (const TileLatency& t : warm.metrics.latencies()) steady_tiles += t.needed >= seconds_to_ticks(1.0);
  CHECK(warm.summary["latency_ms"]["tiles"] == steady_tiles);
  CHECK(steady_tiles < warm.metrics.latencies().size());
  // The warm-up changes no frame: the same run, measured differently.
  REQUIRE(warm.metrics.frames().size() == frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) CHECK(warm.metrics.frames()[i] == frames[i]);
}

TEST_CASE("metrics: the walk on HDD against NVMe: fewer served, a lower p95, and compare does not call it better") {
  const Trace walk = load_trace(std::string(VTSIM_SOURCE_DIR) + "/traces/walk.csv");
  const auto replay = [&](const char* preset) {
    const ReplayConfig cfg = load_replay_config("", {std::string("disk.preset=") + preset});
    auto scene = make_scene_from_config(cfg);
    return run_replay(cfg, walk, *scene).summary;
  };
  const nlohmann::json nvme = replay("nvme"), hdd = replay("hdd");
  // The figures: p95 716.7 -> 533.3 ms while blur doubled and 168,704 tiles were throttled.
  CHECK(nvme["latency_ms"]["p95"].get<double>() == doctest::Approx(716.667).epsilon(1e-5));
  CHECK(hdd["latency_ms"]["p95"].get<double>() == doctest::Approx(533.333).epsilon(1e-5));
  CHECK(hdd["throttle"]["requests_throttled"] == 168704);
  CHECK(nvme["latency_ms"]["served_fraction"].get<double>() == 1156.0 / 1164.0);
  CHECK(hdd["latency_ms"]["served_fraction"].get<double>() == 1004.0 / 1652.0);
  const CompareReport r = compare_documents(nvme, "nvme.json", hdd, "hdd.json", {});
  std::size_t better = 0;
  for (const MetricDiff& d : r.rows) {
    if (d.key.rfind("latency_ms.", 0) == 0 && d.verdict == Verdict::better) ++better;
    if (d.key == "latency_ms.p95" || d.key == "latency_ms.km.p95") CHECK(d.verdict == Verdict::changed);
    if (d.key == "latency_ms.served_fraction") CHECK(d.verdict == Verdict::worse);
  }
  CHECK(better == 0);
}
