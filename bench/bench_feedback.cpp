// Feedback renderer: run time against error per divisor (docs/view.md, BRIEF §6 "run time
// against error"). For each scene and each standard trace, renders the sampled frames at divisors
// 1, 2, 4, 8, 16 and reports, per divisor: the median render time per frame (one core), the
// median feedback-aggregation time, and the error against divisor 1 measured in the same run:
//  - tiles missed: the fraction of divisor 1's tile set (128-texel tiles), weighted by divisor 1's
//    sample counts, that the divisor's tile set lacks (mean and max over frames);
//  - pop-in error: |blurry fraction at the divisor − blurry fraction at divisor 1| for the same
//    fixed synthetic residency (mean and max over frames);
//  - the same tile error after add_level_seams, its time, and the extra tiles it requests that
//    divisor 1 does not touch (false positives, as a fraction of divisor 1's tile count).
// Usage: bench_feedback [--scenes plane,heightfield,town] [--frames N] [common harness flags:
// --quick --reps N --json FILE --filter S ...]. The harness lines: render ms per frame at each
// divisor against divisor 1 on the same frames (ratio = speed-up); the full report is the JSON's
// params.report. Then the fast paths at divisor 8 against their references (span renderers, and
// the town's occlusion culling); --fast-paths-only runs only those.
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <string>
#include <unordered_map>
#include <vector>

#include <time.h>

#include "core/tile_key.h"
#include "core/camera.h"
#include "stream/system/feedback.h"
#include "sim/run/popin.h"
#include "sim/view/scene.h"
#include "sim/view/scene_heightfield.h"
#include "sim/view/scene_mesh.h"
#include "sim/view/scene_town.h"
#include "harness.h"

using namespace vtsim;

namespace {

constexpr int kDivisors[] = {1, 2, 4, 8, 16};
constexpr int kTileSize = 128;  // texels, Yao 2011's page size
constexpr double kFps = 60.0;

// Ground height under (x, y) for placing cameras "at 1.7 m".
using GroundFn = double (*)(const IScene&, double, double);

struct TraceSpec {
  glm::dvec3 start;  // x, y, and z above ground
  double yaw_deg;
};

// Stand-ins for the standard traces (generate_trace is being written in parallel): same speeds,
// heights and manoeuvres. The input of the benchmark is a list of Trace objects, so the real
// generator drops in here.
std::vector<Trace> standard_traces(const IScene& scene, GroundFn ground, const TraceSpec& at, double seconds) {
  const auto make = [&](const std::string& name, auto pose_at) {
    Trace t;
    t.name = name;
    const int n = static_cast<int>(seconds * kFps);
    for (int i = 0; i < n; ++i) {
      const double ts = i / kFps;
      Pose p = pose_at(ts);
      p.t_s = ts;
      p.pos_m.z += ground(scene, p.pos_m.x, p.pos_m.y);
      t.poses.push_back(p);
    }
    return t;
  };
  const double c = std::cos(at.yaw_deg * M_PI / 180.0), s = std::sin(at.yaw_deg * M_PI / 180.0);
  const auto along = [&](double d, double h) { return glm::dvec3(at.start.x + c * d, at.start.y + s * d, h); };
  std::vector<Trace> out;
  out.push_back(make("walk 1.5 m/s at 1.7 m", [&](double t) {
    return pose_from_angles(along(1.5 * t, 1.7 + 0.03 * std::sin(2 * M_PI * 1.8 * t)),
                            at.yaw_deg + 5.0 * std::sin(2 * M_PI * 0.3 * t), -5.0, 0.0, 60.0);
  }));
  out.push_back(make("run 5 m/s at 1.7 m", [&](double t) {
    return pose_from_angles(along(5.0 * t, 1.7 + 0.06 * std::sin(2 * M_PI * 2.8 * t)), at.yaw_deg, -8.0, 0.0, 60.0);
  }));
  out.push_back(make("drive 20 m/s at 1.5 m", [&](double t) {
    return pose_from_angles(along(20.0 * t, 1.5), at.yaw_deg, -2.0, 0.0, 60.0);
  }));
  out.push_back(make("flight 100 m/s at 300 m", [&](double t) {
    return pose_from_angles(along(100.0 * t, 300.0), at.yaw_deg, -20.0, 0.0, 60.0);
  }));
  out.push_back(make("quick 180 deg turn", [&](double t) {
    const double k = std::clamp((t - 0.25 * seconds) / 0.5, 0.0, 1.0);  // 180° in 0.5 s
    return pose_from_angles(along(0.0, 1.7), at.yaw_deg + 180.0 * k * k * (3 - 2 * k), -5.0, 0.0, 60.0);
  }));
  out.push_back(make("teleport 2 km", [&](double t) {
    const double jump = t < 0.5 * seconds ? 0.0 : 2000.0;
    return pose_from_angles(glm::dvec3(at.start.x + jump * s, at.start.y + jump * c * 0.5, 1.7), at.yaw_deg, -5.0,
                            0.0, 60.0);
  }));
  return out;
}

double ground_plane(const IScene&, double, double) { return 0.0; }
double ground_heightfield(const IScene& s, double x, double y) {
  const double h = static_cast<const HeightfieldScene&>(s).height_at(x, y);
  return std::isfinite(h) ? h : 0.0;
}

// The fixed synthetic residency of the pop-in error: levels >= k resident everywhere, finer
// levels l only within R level-l texels (Chebyshev) of the camera's ground point — a clipmap of
// clipsize 2R whose stack stops at level k.
struct RingResidency final : IResidency {
  std::int64_t cu, cv, r;
  int k, n;
  int resident_level(std::int64_t u, std::int64_t v, int d) const override {
    for (int l = d; l < k; ++l)
      if (std::llabs((u >> l) - (cu >> l)) < r && std::llabs((v >> l) - (cv >> l)) < r) return l;
    return std::max(d, k);
  }
  int num_levels() const override { return n; }
};

// CPU time of the calling thread, ms: the cost on one core, robust on a shared machine where
// wall time includes time the thread waited for a core.
double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

struct DivResult {
  std::vector<double> render_ms, aggregate_ms, missed, popin_err;
  std::vector<double> seams_ms, seams_missed, seams_extra, extra;  // with add_level_seams; false positives
  std::vector<double> trace_missed, trace_popin, trace_ms;  // per trace: mean missed, mean pop-in error, median ms
  std::vector<double> cur_ms;
  double samples = 0.0, pixels = 0.0;
};

struct Options {
  std::vector<std::string> scenes = {"plane", "heightfield", "town"};
  int frames = 10;  // sampled frames per trace
  int reps = 3;     // renders per frame and divisor (the median is over all)
  int width = 1920, height = 1080;
  std::vector<std::string> harness_args;  // the common flags, for bench::Harness
  bool fast_only = false;  // only the fast paths against their references
};

// This benchmark's own flags; the common ones (--quick, --reps, --json, ...) go to the harness.
// --quick: 3 frames per trace, 1 repetition. --reps N: renders per frame and divisor.
Options parse(int argc, char** argv) {
  Options o;
  o.harness_args.push_back(argv[0]);
  bool frames_given = false, reps_given = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        fmt::print(stderr, "bench_feedback: {} needs a value\n", a);
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--scenes") {
      o.scenes.clear();
      std::string v = next();
      for (std::size_t p = 0; p <= v.size();) {
        const std::size_t q = std::min(v.find(',', p), v.size());
        o.scenes.push_back(v.substr(p, q - p));
        p = q + 1;
      }
    } else if (a == "--frames") {
      o.frames = std::max(1, std::atoi(next().c_str()));
      frames_given = true;
    } else if (a == "--reps") {
      const std::string v = next();
      o.reps = std::max(1, std::atoi(v.c_str()));
      reps_given = true;
      o.harness_args.push_back(a);
      o.harness_args.push_back(v);
    } else if (a == "--json" || a == "--filter" || a == "--warmup") {
      o.harness_args.push_back(a);
      o.harness_args.push_back(next());
    } else if (a == "--fast-paths-only") {
      o.fast_only = true;
    } else if (a == "--quick" || a == "--strict" || a == "--help" || a == "-h") {
      o.harness_args.push_back(a);
    } else {
      fmt::print(stderr, "usage: bench_feedback [--scenes plane,heightfield,town] [--frames N] [--quick] [--reps N] "
                         "[--json FILE] [--filter S] [--fast-paths-only]\n");
      std::exit(2);
    }
  }
  const char* q = std::getenv("VTSIM_BENCH_QUICK");
  const bool quick = std::find(o.harness_args.begin(), o.harness_args.end(), "--quick") != o.harness_args.end() ||
                     (q && std::string(q) != "" && std::string(q) != "0");
  if (quick && !frames_given) o.frames = 3;
  if (quick && !reps_given) o.reps = 1;
  return o;
}

// The fast paths at divisor 8 against their straightforward references, side by side on the
// same frames (medians of thread CPU time per frame, one core): the scene's span renderer plus
// span aggregation (the replay's view work) against render() plus per-sample aggregation — for
// the town, render() drawing every chunk in the frustum in index order (no occlusion culling).
// Both sides give identical results (tests/test_view_spans.cpp, tests/test_view_town.cpp).
void fast_paths(const Options& opt, nlohmann::json& report) {
  fmt::print("\nfast paths at divisor 8 (median ms per frame; reference side by side)\n");
  for (const std::string& name : {std::string("plane"), std::string("town")}) {
    if (std::find(opt.scenes.begin(), opt.scenes.end(), name) == opt.scenes.end()) continue;
    SceneConfig cfg;
    cfg.kind = find_scene(name).name;
    const std::unique_ptr<IScene> scene = make_scene(cfg);
    const std::unique_ptr<IScene> ref_scene = make_scene(cfg);
    if (cfg.kind == "town") dynamic_cast<MeshScene&>(*ref_scene).set_occlusion_culling(false);
    const TraceSpec at = cfg.kind == "town" ? TraceSpec{{30.0, 8.0, 0.0}, 0.0} : TraceSpec{{4096.0, 4096.0, 0.0}, 30.0};
    const std::vector<Trace> traces = standard_traces(*scene, ground_plane, at, 2.0);
    const int levels = mip_level_count(scene->texture());
    ViewParams vp;
    vp.divisor = 8;
    ViewBuffer vb;
    SpanBuffer sb;
    std::vector<TileUse> tiles;
    nlohmann::json jt = nlohmann::json::object();
    for (const Trace& tr : traces) {
      std::vector<double> fast_ms, ref_ms;
      const int n = static_cast<int>(tr.poses.size());
      for (int fi = 0; fi < opt.frames; ++fi) {
        const Camera cam =
            make_camera(tr.poses[static_cast<std::size_t>((static_cast<long long>(fi) * n) / opt.frames)], opt.width, opt.height);
        for (int rep = 0; rep < opt.reps; ++rep) {
          for (int side = 0; side < 2; ++side) {  // alternate, so drifts in machine load hit both
            const bool fast = (rep + side) % 2 == 0;
            const double t0 = thread_cpu_ms();
            if (fast) {
              scene->render_spans(cam, vp, sb);
              aggregate_feedback(sb, kTileSize, levels, tiles);
            } else {
              ref_scene->render(cam, vp, vb);
              aggregate_feedback(vb, kTileSize, levels, tiles);
            }
            (fast ? fast_ms : ref_ms).push_back(thread_cpu_ms() - t0);
          }
        }
      }
      const double f = median(fast_ms), r = median(ref_ms);
      fmt::print("  {:<6} {:<9} fast {:.4f} ms  reference {:.4f} ms  x{:.1f}\n", name, tr.name, f, r, r / f);
      jt[tr.name] = {{"fast_ms", f}, {"reference_ms", r}};
    }
    report["fast_paths_divisor8"][name] = jt;
  }
}

}  // namespace

int main(int argc, char** argv) {
  Options opt = parse(argc, argv);
  std::vector<char*> hargv;
  for (auto& a : opt.harness_args) hargv.push_back(a.data());
  bench::Harness h("feedback", static_cast<int>(hargv.size()), hargv.data(), 3, 1,
                   "  --scenes LIST   plane,heightfield,town (default all three)\n"
                   "  --frames N      sampled frames per trace (default 10; quick 3)\n"
                   "  --fast-paths-only  only the fast paths against their references\n");
  nlohmann::json report = nlohmann::json::object();
  report["image"] = {opt.width, opt.height};
  report["tile_size_texels"] = kTileSize;
  report["frames_per_trace"] = opt.frames;
  report["reps"] = opt.reps;
  fmt::print("feedback renderer, {}x{} image, {} frames per trace x {} reps, tile {} texels, one core\n", opt.width,
             opt.height, opt.frames, opt.reps, kTileSize);
  for (const std::string& name : opt.scenes) {
    if (opt.fast_only) break;
    SceneConfig cfg;
    cfg.kind = find_scene(name).name;
    TraceSpec at{{4096.0, 4096.0, 0.0}, 30.0};
    GroundFn ground = ground_plane;
    if (cfg.kind == "town") at = TraceSpec{{30.0, 8.0, 0.0}, 0.0};  // along the first street
    if (cfg.kind == "heightfield") ground = ground_heightfield;
    const std::unique_ptr<IScene> scene = make_scene(cfg);
    const int levels = mip_level_count(scene->texture());
    const std::vector<Trace> traces = standard_traces(*scene, ground, at, 2.0);

    std::vector<DivResult> res(std::size(kDivisors));
    ViewBuffer vb, ref_vb;
    std::vector<TileUse> tiles, ref_tiles;
    std::vector<std::int8_t> lv;
    std::unordered_map<std::uint64_t, std::uint32_t> ref_set;
    for (const Trace& tr : traces) {
      const int n = static_cast<int>(tr.poses.size());
      std::vector<std::size_t> first_frame(res.size());
      for (std::size_t di = 0; di < res.size(); ++di) {
        first_frame[di] = res[di].missed.size();
        res[di].cur_ms.clear();
      }
      for (int fi = 0; fi < opt.frames; ++fi) {
        const Pose& pose = tr.poses[static_cast<std::size_t>((static_cast<long long>(fi) * n) / opt.frames)];
        const Camera cam = make_camera(pose, opt.width, opt.height);
        RingResidency residency;
        residency.cu = static_cast<std::int64_t>(std::floor(pose.pos_m.x * cfg.texels_per_m));
        residency.cv = static_cast<std::int64_t>(std::floor(pose.pos_m.y * cfg.texels_per_m));
        residency.r = 512;  // level-l texels: 4 m of level 0, 128 m of level 5
        residency.k = 6;
        residency.n = levels;
        double ref_blurry = 0.0;
        std::uint64_t ref_total = 0;
        for (std::size_t di = 0; di < std::size(kDivisors); ++di) {
          ViewParams vp;
          vp.divisor = kDivisors[di];
          DivResult& r = res[di];
          for (int rep = 0; rep < opt.reps; ++rep) {
            const double t0 = thread_cpu_ms();
            scene->render(cam, vp, vb);
            const double t1 = thread_cpu_ms();
            aggregate_feedback(vb, kTileSize, levels, tiles);
            const double t2 = thread_cpu_ms();
            r.render_ms.push_back(t1 - t0);
            r.cur_ms.push_back(t1 - t0);
            r.aggregate_ms.push_back(t2 - t1);
          }
          r.samples += static_cast<double>(vb.samples.size());
          r.pixels += static_cast<double>(vb.width) * vb.height;
          resident_levels(vb, residency, lv);
          const PopinFrame pf = popin_stats(vb, lv, nullptr, levels);
          if (di == 0) {
            ref_set.clear();
            ref_total = 0;
            for (const TileUse& t : tiles) {
              ref_set[t.key.bits] = t.samples;
              ref_total += t.samples;
            }
            ref_blurry = pf.blurry_fraction;
          }
          const auto score = [&](const std::vector<TileUse>& ts, std::vector<double>& missed, std::vector<double>& extra) {
            std::uint64_t hit = 0, wrong = 0;
            for (const TileUse& t : ts) {
              if (auto it = ref_set.find(t.key.bits); it != ref_set.end()) hit += it->second;
              else ++wrong;
            }
            missed.push_back(ref_total ? 1.0 - static_cast<double>(hit) / static_cast<double>(ref_total) : 0.0);
            extra.push_back(ref_set.empty() ? 0.0 : static_cast<double>(wrong) / static_cast<double>(ref_set.size()));
          };
          score(tiles, r.missed, r.extra);
          const double s0 = thread_cpu_ms();
          add_level_seams(vb, kTileSize, levels, tiles);
          r.seams_ms.push_back(thread_cpu_ms() - s0);
          score(tiles, r.seams_missed, r.seams_extra);
          r.popin_err.push_back(std::fabs(pf.blurry_fraction - ref_blurry));
        }
      }
      for (std::size_t di = 0; di < res.size(); ++di) {
        DivResult& r = res[di];
        double m = 0.0, pe = 0.0;
        const std::size_t k = r.missed.size() - first_frame[di];
        for (std::size_t i = first_frame[di]; i < r.missed.size(); ++i) {
          m += r.missed[i] / static_cast<double>(k);
          pe += r.popin_err[i] / static_cast<double>(k);
        }
        r.trace_missed.push_back(m);
        r.trace_popin.push_back(pe);
        r.trace_ms.push_back(median(r.cur_ms));
      }
    }
    fmt::print("\nscene {} ({} traces: walk, run, drive, flight, 180 deg turn, teleport)\n", name, traces.size());
    fmt::print("{:>7} {:>9} {:>10} {:>9} {:>9} {:>8} {:>10} {:>10} {:>10} {:>10} | {:>8} {:>10} {:>10} {:>10}\n",
               "divisor", "samples", "render ms", "ns/pixel", "speed-up", "aggr ms", "missed avg", "missed max",
               "pop-in avg", "pop-in max", "seams ms", "missed avg", "missed max", "extra avg");
    nlohmann::json jdivs = nlohmann::json::array();
    const double ref_ms = median(res[0].render_ms);
    for (std::size_t di = 0; di < std::size(kDivisors); ++di) {
      const DivResult& r = res[di];
      const double ms = median(r.render_ms), ams = median(r.aggregate_ms);
      const double frames = static_cast<double>(r.missed.size());
      double miss_avg = 0, miss_max = 0, pop_avg = 0, pop_max = 0;
      for (double m : r.missed) {
        miss_avg += m / frames;
        miss_max = std::max(miss_max, m);
      }
      for (double p : r.popin_err) {
        pop_avg += p / frames;
        pop_max = std::max(pop_max, p);
      }
      const double px_per_frame = r.pixels / frames;
      double smiss_avg = 0, smiss_max = 0, sextra = 0, extra = 0;
      for (double m : r.seams_missed) {
        smiss_avg += m / frames;
        smiss_max = std::max(smiss_max, m);
      }
      for (double e : r.seams_extra) sextra += e / frames;
      for (double e : r.extra) extra += e / frames;
      const double sms = median(r.seams_ms);
      fmt::print("{:>7} {:>9.0f} {:>10.4f} {:>9.2f} {:>8.1f}x {:>8.4f} {:>9.3f}% {:>9.3f}% {:>9.4f}% {:>9.4f}% | {:>8.4f} "
                 "{:>9.3f}% {:>9.3f}% {:>9.3f}%\n",
                 kDivisors[di], r.samples / frames, ms, ms * 1e6 / px_per_frame, ref_ms / ms, ams, 100 * miss_avg,
                 100 * miss_max, 100 * pop_avg, 100 * pop_max, sms, 100 * smiss_avg, 100 * smiss_max, 100 * sextra);
      jdivs.push_back({{"divisor", kDivisors[di]},
                       {"samples_per_frame", r.samples / frames},
                       {"render_ms_median", ms},
                       {"ns_per_buffer_pixel", ms * 1e6 / px_per_frame},
                       {"speedup_vs_divisor_1", ref_ms / ms},
                       {"aggregate_ms_median", ams},
                       {"tiles_missed_mean", miss_avg},
                       {"tiles_missed_max", miss_max},
                       {"popin_error_mean", pop_avg},
                       {"popin_error_max", pop_max},
                       {"extra_tiles_mean", extra},
                       {"seams_ms_median", sms},
                       {"seams_tiles_missed_mean", smiss_avg},
                       {"seams_tiles_missed_max", smiss_max},
                       {"seams_extra_tiles_mean", sextra}});
    }
    fmt::print("per trace: median render ms / tiles missed mean / pop-in error mean, at divisors 1 and 8\n");
    nlohmann::json jtr = nlohmann::json::array();
    for (std::size_t ti = 0; ti < traces.size(); ++ti) {
      fmt::print("  {:<26} d1 {:>9.3f} ms   d8 {:>8.4f} ms {:>8.4f}% {:>8.4f}%\n", traces[ti].name, res[0].trace_ms[ti],
                 res[3].trace_ms[ti], 100 * res[3].trace_missed[ti], 100 * res[3].trace_popin[ti]);
      jtr.push_back({{"trace", traces[ti].name},
                     {"divisor_1_render_ms", res[0].trace_ms[ti]},
                     {"divisor_8_render_ms", res[3].trace_ms[ti]},
                     {"divisor_8_tiles_missed_mean", res[3].trace_missed[ti]},
                     {"divisor_8_popin_error_mean", res[3].trace_popin[ti]}});
    }
    report["scenes"][name] = {{"divisors", jdivs}, {"traces", jtr}};
    // Render time per frame against divisor 1 on the same frames, rendered back to back.
    for (std::size_t di = 1; di < std::size(kDivisors); ++di)
      h.add_measured({.name = name + "_divisor" + std::to_string(kDivisors[di]),
                      .metric = bench::Metric::kMsPerRep,
                      .work = 1,
                      .params = {{"scene", name}, {"divisor", kDivisors[di]}, {"frames_per_trace", opt.frames},
                                 {"what", "render ms per frame, one core (thread CPU time)"}},
                      .target_ratio = 0},
                     "divisor " + std::to_string(kDivisors[di]), res[di].render_ms, "divisor 1", res[0].render_ms);
  }
  fast_paths(opt, report);
  h.param("report", report);
  return h.finish();
}
