// Run time against error for every fidelity knob of a simulated replay (brief §6, issue 7):
// feedback divisor (view.divisor), pop-in sampling divisor (view.popin_divisor) and feedback every
// k frames (view.feedback_every). For each knob and setting, every trace is replayed in the
// simulated clock and its summary metrics are compared with the knob's highest-fidelity setting,
// replayed in the same run: the table gives the CPU time per frame, the speed-up over that
// reference (median of the per-repetition pairs), and the error of the metrics that matter.
// There is no event-batching knob: the simulated clock is exact (integer-nanosecond event queue,
// completions consumed at each frame's time), so nothing there trades accuracy for speed.
//
// Traces: the standard walk, drive, flight, turn and teleport (traces/) and the real handheld
// (TUM fr1_xyz) and drone (EuRoC V1_02) recordings (shared/traces-real/) imported onto the terrain,
// each cut to a window centred on the trace (the turn and the teleport at its middle): 5 s, quick
// 0.5 s on walk and turn only (VTSIM_FIDELITY_SECONDS overrides). One repetition unless --reps. Scene: the default plane, 2^20² texels, 1920×1080, 60 Hz; default config otherwise.
//
//   build/bench/bench_fidelity [--quick] [--reps N] [--filter divisor] [--json FILE]
//   VTSIM_FIDELITY_SECONDS=20 build/bench/bench_fidelity     (longer windows)
// Prints one markdown table per knob (docs/performance.md) and the harness lines (ratio =
// speed-up over the highest-fidelity setting).
#include <fmt/format.h>
#include <time.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "core/error.h"
#include "harness.h"
#include "sim/run/replay.h"
#include "sim/view/scene.h"
#include "sim/trace/trace_import.h"

namespace {

using namespace vtsim;
namespace fs = std::filesystem;

double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// The poses within [mid − seconds/2, mid + seconds/2] of the trace's time span, times kept.
Trace window(const Trace& t, double seconds) {
  const double t0 = t.poses.front().t_s, t1 = t.poses.back().t_s;
  const double start = t0 + std::max(0.0, (t1 - t0 - seconds) / 2.0);
  Trace out = t;
  out.poses.clear();
  for (const Pose& p : t.poses)
    if (p.t_s >= start && p.t_s <= start + seconds) out.poses.push_back(p);
  return out;
}

struct Input {
  std::string name;
  Trace trace;
};

std::vector<Input> in_standard(const fs::path& root, const std::vector<std::string>& names, double seconds) {
  std::vector<Input> in;
  for (const auto& n : names) in.push_back({n, window(load_any_trace((root / "traces" / (n + ".csv")).string()), seconds)});
  return in;
}

std::vector<Input> load_inputs(const fs::path& root, double seconds, bool quick) {
  const std::vector<std::string> standard =
      quick ? std::vector<std::string>{"walk", "turn"} : std::vector<std::string>{"walk", "drive", "flight", "turn", "teleport"};
  std::vector<Input> in = in_standard(root, standard, seconds);
  if (quick) return in;
  // Real recordings: the handheld Kinect at eye height, room scale (metres stay metres); the
  // drone 10× larger at 30 m (a 40 m room flight becomes a 400 m one at 9 m/s median, 22 m/s max).
  const fs::path real = root / ".." / "shared" / "traces-real";
  ImportOptions hand;
  hand.transform.recenter = true;
  hand.transform.offset_m = {4096.0, 4096.0, 1.7};
  in.push_back({"handheld", window(import_trace((real / "tum_fr1_xyz_groundtruth.txt").string(), hand), seconds)});
  ImportOptions drone;
  drone.transform.recenter = true;
  drone.transform.scale = 10.0;
  drone.transform.offset_m = {4096.0, 4096.0, 30.0};
  in.push_back({"drone", window(import_trace((real / "euroc_V1_02_groundtruth.csv").string(), drone), seconds)});
  return in;
}

// The summary metrics the error is measured on.
struct Metrics {
  double blurry = 0;      // popin.blurry_fraction_mean
  double deficit = 0;     // popin.mean_deficit, levels
  double lat_p50 = 0;     // latency_ms.p50
  double lat_p95 = 0;     // latency_ms.p95
  double disk = 0;        // bandwidth.disk_read_MBps
  double pops = 0;        // visible pops per measured sample (the count scales with the buffer)
  double tts = 0;         // popin.time_to_sharp_s.mean, s
  double tiles = 0;       // latency_ms.tiles
  int frames = 0;
};

Metrics extract(const ReplayResult& r) {
  const auto& s = r.summary;
  Metrics m;
  m.blurry = s["popin"]["blurry_fraction_mean"].get<double>();
  m.deficit = s["popin"]["mean_deficit"].get<double>();
  m.lat_p50 = s["latency_ms"]["p50"].get<double>();
  m.lat_p95 = s["latency_ms"]["p95"].get<double>();
  m.disk = s["bandwidth"]["disk_read_MBps"].get<double>();
  const auto& tts = s["popin"]["time_to_sharp_s"]["mean"];  // null: no event became sharp
  m.tts = tts.is_number() ? tts.get<double>() : std::numeric_limits<double>::quiet_NaN();
  m.tiles = s["latency_ms"]["tiles"].get<double>();
  m.frames = s["trace"]["frames"].get<int>();
  double samples = 0;
  for (const auto& f : r.metrics.frames())
    if (f.measured) samples += f.samples;
  m.pops = samples > 0 ? static_cast<double>(s["popin"]["visible_pops"].get<std::uint64_t>()) / samples : 0.0;
  return m;
}

// Relative error in %, or absolute when the reference is 0.
double rel_pct(double v, double ref) { return ref != 0 ? 100.0 * std::fabs(v - ref) / std::fabs(ref) : 100.0 * std::fabs(v); }

struct Errors {
  double blurry_pp, deficit, lat_p50_pct, lat_p95_pct, disk_pct, pops_pct, tts_s;
};

Errors errors(const Metrics& m, const Metrics& ref) {
  return {100.0 * std::fabs(m.blurry - ref.blurry), std::fabs(m.deficit - ref.deficit), rel_pct(m.lat_p50, ref.lat_p50),
          rel_pct(m.lat_p95, ref.lat_p95),           rel_pct(m.disk, ref.disk),           rel_pct(m.pops, ref.pops),
          std::isnan(m.tts) && std::isnan(ref.tts) ? 0.0 : std::fabs(m.tts - ref.tts)};  // both without a time to sharp: equal
}

struct Setting {
  std::string label;                // as printed, e.g. "8"
  std::vector<std::string> sets;    // config overrides
};

struct Knob {
  std::string key;                  // "view.divisor"
  std::string fixed;                // the other knobs, as printed
  std::vector<std::string> base;    // overrides common to every setting
  std::vector<Setting> settings;    // settings[0] is the highest fidelity: the reference
};

struct Run {
  Metrics m;
  std::vector<double> cpu_s;        // per repetition
};

// Replays `trace` with the config overrides `sets`; the metrics replace run.m (they are the same
// every repetition: the simulated clock is deterministic) and the CPU time joins run.cpu_s.
void replay_into(const std::vector<std::string>& sets, const Trace& trace, Run& run) {
  const ReplayConfig cfg = load_replay_config("", sets);
  const auto scene = make_scene_from_config(cfg);
  const double c0 = thread_cpu_s();
  const ReplayResult r = run_replay(cfg, trace, *scene);
  run.cpu_s.push_back(thread_cpu_s() - c0);
  run.m = extract(r);
}

// Settings are listed highest fidelity first (the reference); 0 for popin_divisor means "the
// feedback buffer itself".
Knob make_knob(const std::string& key, const std::string& fixed, const std::vector<std::string>& base,
               const std::vector<int>& values) {
  Knob k;
  k.key = key;
  k.fixed = fixed;
  k.base = base;
  for (int v : values) {
    Setting s;
    s.label = v == 0 ? std::string("8 (= feedback)") : std::to_string(v);
    s.sets.push_back(key + "=" + std::to_string(v));
    k.settings.push_back(std::move(s));
  }
  return k;
}

std::vector<Knob> make_knobs(bool quick) {
  std::vector<Knob> k;
  k.push_back(make_knob("view.divisor", "pop-in measured on the feedback buffer, feedback every frame", {},
                        quick ? std::vector<int>{1, 8, 16} : std::vector<int>{1, 2, 4, 8, 16}));
  k.push_back(make_knob("view.popin_divisor", "feedback divisor 8, every frame", {"view.divisor=8"},
                        quick ? std::vector<int>{1, 0} : std::vector<int>{1, 2, 4, 0}));
  k.push_back(make_knob("view.feedback_every", "feedback divisor 8, pop-in on the feedback buffer", {"view.divisor=8"},
                        quick ? std::vector<int>{1, 4} : std::vector<int>{1, 2, 3, 4, 8}));
  return k;
}

std::string mean_max(const std::vector<double>& v, const char* fmt_spec) {
  double sum = 0, mx = 0;
  for (double x : v) {
    sum += x;
    mx = std::max(mx, x);
  }
  const double mean = v.empty() ? 0 : sum / static_cast<double>(v.size());
  return fmt::format(fmt::runtime(std::string("{:") + fmt_spec + "} / {:" + fmt_spec + "}"), mean, mx);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace vtsim;
  bench::Harness h("fidelity", argc, argv, 1, 1);
  const bool quick = h.quick();
  double seconds = h.pick(5.0, 0.5);
  if (const char* s = std::getenv("VTSIM_FIDELITY_SECONDS")) {
    char* end = nullptr;
    const double v = std::strtod(s, &end);
    if (end == s || *end != '\0' || !(v > 0) || v > 3600) {
      fmt::print(stderr, "bench_fidelity: VTSIM_FIDELITY_SECONDS='{}': expected seconds in (0, 3600]\n", s);
      return 2;
    }
    seconds = v;
  }
  const fs::path root = fs::path(__FILE__).parent_path() / "..";
  std::vector<Input> inputs;
  try {
    inputs = load_inputs(root, seconds, quick);
  } catch (const InputError& e) {
    fmt::print(stderr, "bench_fidelity: {}\n", e.what());
    return 2;
  }
  int total_frames_in = 0;
  for (const auto& i : inputs) total_frames_in += static_cast<int>(i.trace.poses.size());
  h.param("seconds_per_trace", seconds);
  h.param("traces", [&] {
    nlohmann::json a = nlohmann::json::array();
    for (const auto& i : inputs) a.push_back(i.name);
    return a;
  }());
  h.param("scene", "plane, 2^20 x 2^20 texels at 128 texels/m, 1920x1080, 60 Hz, default config");

  const std::vector<Knob> knobs = make_knobs(quick);

  const int reps = h.options().reps;
  std::string tables;
  for (const Knob& k : knobs) {
    if (!h.selected(k.key)) continue;
    // runs[setting][trace]; repetitions interleave the settings (reference first on even
    // repetitions, last on odd ones) so that load drifting over the run hits every setting.
    std::vector<std::vector<Run>> runs(k.settings.size(), std::vector<Run>(inputs.size()));
    for (int rep = 0; rep < reps; ++rep) {
      for (std::size_t ti = 0; ti < inputs.size(); ++ti) {
        for (std::size_t j = 0; j < k.settings.size(); ++j) {
          const std::size_t si = rep % 2 == 0 ? j : k.settings.size() - 1 - j;
          std::vector<std::string> sets = k.base;
          sets.insert(sets.end(), k.settings[si].sets.begin(), k.settings[si].sets.end());
          replay_into(sets, inputs[ti].trace, runs[si][ti]);
        }
      }
      fmt::print(stderr, "bench_fidelity: {} repetition {}/{} done\n", k.key, rep + 1, reps);
    }
    // Per repetition: CPU seconds summed over the traces.
    std::vector<std::vector<double>> total(k.settings.size(), std::vector<double>(static_cast<std::size_t>(reps), 0.0));
    for (std::size_t si = 0; si < k.settings.size(); ++si)
      for (std::size_t ti = 0; ti < inputs.size(); ++ti)
        for (int rep = 0; rep < reps; ++rep) total[si][static_cast<std::size_t>(rep)] += runs[si][ti].cpu_s[static_cast<std::size_t>(rep)];
    int frames = 0;
    double duration_s = 0;
    for (std::size_t ti = 0; ti < inputs.size(); ++ti) {
      frames += runs[0][ti].m.frames;
      duration_s += static_cast<double>(runs[0][ti].m.frames) / 60.0;
    }

    std::string t = fmt::format("\n### `{}` ({}; {} traces, {} frames, {:.0f} s simulated)\n\n", k.key, k.fixed, inputs.size(),
                                frames, duration_s);
    t += "| setting | CPU ms/frame | speed-up | × real time | blurry Δ pp (mean / max) | deficit Δ levels | "
         "latency p50 Δ % | latency p95 Δ % | disk MB/s Δ % | pops/sample Δ % | time-to-sharp Δ s |\n";
    t += "|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (std::size_t si = 0; si < k.settings.size(); ++si) {
      std::vector<double> eb, ed, e50, e95, edisk, epops, etts;
      nlohmann::json per_trace = nlohmann::json::object();
      for (std::size_t ti = 0; ti < inputs.size(); ++ti) {
        const Errors e = errors(runs[si][ti].m, runs[0][ti].m);
        eb.push_back(e.blurry_pp);
        ed.push_back(e.deficit);
        e50.push_back(e.lat_p50_pct);
        e95.push_back(e.lat_p95_pct);
        edisk.push_back(e.disk_pct);
        epops.push_back(e.pops_pct);
        etts.push_back(e.tts_s);
        const Metrics& m = runs[si][ti].m;
        per_trace[inputs[ti].name] = {{"blurry_fraction_mean", m.blurry}, {"mean_deficit", m.deficit},
                                      {"latency_p50_ms", m.lat_p50},      {"latency_p95_ms", m.lat_p95},
                                      {"disk_read_MBps", m.disk},         {"pops_per_sample", m.pops},
                                      {"time_to_sharp_mean_s", m.tts},    {"tiles", m.tiles},
                                      {"blurry_err_pp", e.blurry_pp},     {"deficit_err", e.deficit},
                                      {"latency_p50_err_pct", e.lat_p50_pct}, {"latency_p95_err_pct", e.lat_p95_pct},
                                      {"disk_err_pct", e.disk_pct},       {"pops_err_pct", e.pops_pct},
                                      {"time_to_sharp_err_s", e.tts_s}};
      }
      std::vector<double> ms_per_frame;
      for (double s : total[si]) ms_per_frame.push_back(1e3 * s / frames);
      const bench::Summary ours = bench::summarize(ms_per_frame);
      std::vector<double> pair;
      for (std::size_t r = 0; r < total[si].size(); ++r) pair.push_back(total[0][r] / total[si][r]);
      const double speedup = bench::summarize(pair).median;
      const double x_real = duration_s / (ours.median * frames / 1e3);
      t += fmt::format("| {}{}{} | {:.3f} | {:.1f}× | {:.1f}× | {} | {} | {} | {} | {} | {} | {} |\n", si == 0 ? "**" : "",
                       k.settings[si].label, si == 0 ? "** (reference)" : "", ours.median, speedup, x_real,
                       mean_max(eb, ".3f"), mean_max(ed, ".4f"), mean_max(e50, ".1f"), mean_max(e95, ".1f"),
                       mean_max(edisk, ".2f"), mean_max(epops, ".1f"), mean_max(etts, ".3f"));
      // The harness line and JSON: CPU ms for all traces per repetition against the reference's.
      std::vector<double> ours_ms, ref_ms;
      for (std::size_t r = 0; r < total[si].size(); ++r) {
        ours_ms.push_back(1e3 * total[si][r]);
        ref_ms.push_back(1e3 * total[0][r]);
      }
      bench::Case c{.name = k.key + "=" + k.settings[si].label.substr(0, k.settings[si].label.find(' ')),
                    .metric = bench::Metric::kMsPerRep,
                    .work = 1,
                    .params = {{"knob", k.key},
                               {"setting", k.settings[si].label},
                               {"fixed", k.fixed},
                               {"frames", frames},
                               {"cpu_ms_per_frame", ours.median},
                               {"blurry_err_pp_max", *std::max_element(eb.begin(), eb.end())},
                               {"disk_err_pct_max", *std::max_element(edisk.begin(), edisk.end())},
                               {"per_trace", per_trace}},
                    .target_ratio = 0};
      // The reference row has no ratio of its own: every other row carries its timing.
      if (si > 0) h.add_measured(c, k.settings[si].label, ours_ms, k.key + "=" + k.settings[0].label, ref_ms);
    }
    tables += t;
  }
  fmt::print("{}\n", tables);
  return h.finish();
}
