// vtsim gl: the headless OpenGL reference client (docs/gpu.md). `gl render` draws a scene along a
// trace (main pass and feedback pass, feedback read back k frames late); `gl check` compares the
// GPU's feedback with the simulator's GPU model (view.lod_model = gpu) and the analytic model.
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <filesystem>
#include <memory>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "cli/cli_io.h"
#include "cli/commands.h"
#include "cli/trace_load.h"
#include "core/camera.h"
#include "core/error.h"
#include "core/image_io.h"
#include "sim/view/gpu_model.h"
#include "sim/view/scene.h"
#include "sim/view/scene_town.h"
#ifdef VTSIM_HAVE_GL
#include "gl/gl_check.h"
#include "gl/gl_context.h"
#include "gl/gl_renderer.h"
#include "gl/gl_replay.h"
#include "stream/store/tile_store.h"
#include "stream/system/vt_system.h"
#endif
#include "cli/config_load.h"

namespace vtsim::cli {

namespace gl_cmd {

struct GlOptions {
  std::string scene = kTownScene;
  std::string file;
  double mesh_unit_m = 1.0;  // mesh (assimp): metres per file unit
  unsigned long long seed = 1;
  int noise_posts = 1025;
  double shift_m = 0.0;      // the whole world and the camera moved by (shift, shift, 0)
  std::string trace;
  bool allow_repairs = false;
  std::string size;          // WxH; default: the trace's
  int divisor = 8;
  float lod_bias = 0.0f;
  float aniso = 0.0f;
  int latency = 2;
  bool latency_set = false;
  bool sampling_set = false;  // gl replay: --sampling given (else view.feedback_sampling)  // gl replay: --latency given (else view.feedback_latency)
  std::string sampling = "middle";
  long long frames = 0;      // 0: the whole trace
  long long every = 1;       // use every Nth trace frame
  std::string frames_png;
  std::string video;
  long long png_every = 60;
  int tile_size = 128;
  std::string divisors = "1,8,16";
  bool json = false;
  // gl replay
  std::vector<std::string> configs, sets;
  std::string store, summary, frames_csv, record_feedback;
  bool no_pace = false;
};

void parse_size(const std::string& s, int& w, int& h) {
  if (std::sscanf(s.c_str(), "%dx%d", &w, &h) != 2 || w < 1 || h < 1 || w > kMaxImageSide || h > kMaxImageSide)
    throw InputError("--size", "expected WxH, got '" + s + "'");
}

SceneConfig scene_config(const GlOptions& o) {
  SceneConfig cfg;
  cfg.kind = find_scene(o.scene).name;
  cfg.file = o.file;
  cfg.mesh_unit_m = o.mesh_unit_m;
  cfg.seed = o.seed;
  cfg.noise_posts = o.noise_posts;
  if (!std::isfinite(o.shift_m) || std::abs(o.shift_m) > 1e9) throw InputError("--shift", "must be finite, |shift| <= 1e9 m");
  cfg.origin_x_m += o.shift_m;
  cfg.origin_y_m += o.shift_m;
  return cfg;
}

FeedbackSampling sampling_of(const std::string& s) {
  if (s == "middle") return FeedbackSampling::middle;
  if (s == "sequence") return FeedbackSampling::sequence;
  throw InputError("--sampling", "expected middle or sequence, got '" + s + "'");
}

struct Walk {
  Trace trace;
  int w = 0, h = 0;
  std::vector<long long> frames;
};

Walk load_walk(const GlOptions& o) {
  if (o.trace.empty()) throw InputError("--trace", "a trace is required");
  Walk wk;
  wk.trace = load_cli_trace(o.trace, o.allow_repairs);
  wk.w = wk.trace.image_width;
  wk.h = wk.trace.image_height;
  if (!o.size.empty()) parse_size(o.size, wk.w, wk.h);
  if (o.every < 1) throw InputError("--every", "must be >= 1");
  const auto n = static_cast<long long>(wk.trace.poses.size());
  for (long long f = 0; f < n && (o.frames == 0 || static_cast<long long>(wk.frames.size()) < o.frames); f += o.every)
    wk.frames.push_back(f);
  return wk;
}

Camera camera_at(const Walk& wk, long long f, double shift) {
  Pose p = trace_pose(wk.trace, f);
  p.pos_m.x += shift;
  p.pos_m.y += shift;
  return make_camera(p, wk.w, wk.h);
}

#ifdef VTSIM_HAVE_GL

gl::FeedbackSettings settings_of(const GlOptions& o, int divisor) {
  gl::FeedbackSettings fs;
  fs.divisor = divisor;
  fs.lod_bias = o.lod_bias;
  fs.anisotropic = o.aniso > 0.0f;
  if (fs.anisotropic) fs.max_aniso = o.aniso;
  if (o.latency < 0 || o.latency > 16) throw InputError("--latency", "must be in [0, 16]");
  fs.latency = o.latency;
  return fs;
}

void run_render(const GlOptions& o) {
  const SceneConfig cfg = scene_config(o);
  const Walk wk = load_walk(o);
  const FeedbackSampling mode = sampling_of(o.sampling);
  if (o.divisor < 1 || o.divisor > 256) throw InputError("--divisor", "must be in [1, 256]");
  if (o.png_every < 1) throw InputError("--png-every", "must be >= 1");
  if (!o.frames_png.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(o.frames_png, ec);
    if (ec) throw InputError("--frames-png", o.frames_png + ": " + ec.message());
  }
  gl::Context ctx(warn);
  gl::Renderer r(ctx, cfg);
  const gl::FeedbackSettings fs = settings_of(o, o.divisor);
  const int levels = mip_level_count(r.texture());
  gl::FeedbackFrame fb;
  std::uint64_t samples = 0, read = 0;
  std::set<std::tuple<int, std::int64_t, std::int64_t>> tiles;
  const auto count = [&](const gl::FeedbackFrame& f) {
    ++read;
    for (const gl::FeedbackTexel& t : f.px)
      if (t.status == 1) {
        ++samples;
        const float lod = t.lod;
        const int l = desired_level(lod, levels);
        tiles.insert({l, (t.u >> l) / o.tile_size, (t.v >> l) / o.tile_size});
      }
  };
  const auto t0 = std::chrono::steady_clock::now();
  long long i = 0;
  for (const long long f : wk.frames) {
    const Camera cam = camera_at(wk, f, o.shift_m);
    r.draw_main(cam, fs);
    int ox = 0, oy = 0;
    feedback_tile_offset(mode, i, o.divisor, ox, oy);
    if (r.feedback(cam, fs, ox, oy, i, fb)) count(fb);
    if (!o.frames_png.empty() && i % o.png_every == 0) {
      int w = 0, h = 0;
      const std::vector<std::uint8_t> px = r.read_main(w, h);
      const std::string path = fmt::format("{}/frame_{:06}.png", o.frames_png, f);
      const auto res = image_io::write_file(path, w, h, 4, image_io::PixelType::u8, px.data(), true);
      if (res.status != image_io::WriteStatus::ok) throw InputError("--frames-png", path + ": " + res.error);
    }
    ++i;
  }
  while (r.drain(fb)) count(fb);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (o.json) {
    nlohmann::json j = {{"renderer", ctx.renderer()}, {"gl_version", ctx.version()}, {"platform", ctx.platform()},
                        {"scene", cfg.kind}, {"triangles", r.triangles()}, {"image", {wk.w, wk.h}},
                        {"feedback", {buffer_extent(wk.w, o.divisor), buffer_extent(wk.h, o.divisor)}},
                        {"frames", i}, {"feedback_frames_read", read}, {"seconds", s}, {"fps", i / s},
                        {"feedback_samples", samples}, {"tiles_touched", tiles.size()}, {"gl_errors", ctx.errors()}};
    fmt::print("{}\n", j.dump(2));
    return;
  }
  fmt::print("{} ({}, {}): {} {} triangles, image {}x{}, feedback {}x{} (divisor {}, {} sampling, read {} frames late)\n",
             ctx.renderer(), ctx.version(), ctx.platform(), cfg.kind, r.triangles(), wk.w, wk.h,
             buffer_extent(wk.w, o.divisor), buffer_extent(wk.h, o.divisor), o.divisor, o.sampling, o.latency);
  fmt::print("{} frames in {:.3f} s: {:.1f} frames/s; {} feedback frames read, {} samples, {} tiles touched; {} GL errors\n",
             i, s, i / s, read, samples, tiles.size(), ctx.errors());
}

void run_check(const GlOptions& o) {
  const SceneConfig cfg = scene_config(o);
  const Walk wk = load_walk(o);
  const FeedbackSampling mode = sampling_of(o.sampling);
  std::vector<int> divisors;
  for (std::size_t a = 0; a < o.divisors.size();) {
    std::size_t b = o.divisors.find(',', a);
    if (b == std::string::npos) b = o.divisors.size();
    const std::string part = o.divisors.substr(a, b - a);
    char* end = nullptr;
    const long d = std::strtol(part.c_str(), &end, 10);
    if (part.empty() || *end != '\0' || d < 1 || d > 256) throw InputError("--divisors", "expected divisors in 1..256, got '" + part + "'");
    divisors.push_back(static_cast<int>(d));
    a = b + 1;
  }
  const std::unique_ptr<IScene> scene = make_scene(cfg);
  for (const std::string& w : scene->load_warnings()) warn(w);
  gl::Context ctx(warn);
  gl::Renderer r(ctx, cfg);
  const int levels = mip_level_count(r.texture());
  nlohmann::json rows = nlohmann::json::array();
  if (!o.json)
    fmt::print("{} {}, {}x{}, {} frames of {}; {} ({})\n"
               "divisor  samples   gpu-model: same  level-off  Jaccard min/mean   analytic: same  level-off  Jaccard min/mean\n",
               cfg.kind, o.sampling, wk.w, wk.h, wk.frames.size(), o.trace, ctx.renderer(), ctx.version());
  for (const int d : divisors) {
    const gl::FeedbackSettings fs = settings_of(o, d);
    ViewParams vp;
    vp.divisor = d;
    vp.lod_bias = o.lod_bias;
    vp.anisotropic = fs.anisotropic;
    vp.max_aniso = fs.max_aniso;
    gl::Agreement gsum, asum;
    double gmin = 1.0, amin = 1.0, gj = 0.0, aj = 0.0;
    long long i = 0;
    ViewBuffer gv, av;
    for (const long long f : wk.frames) {
      const Camera cam = camera_at(wk, f, o.shift_m);
      int ox = 0, oy = 0;
      feedback_tile_offset(mode, i, d, ox, oy);
      const gl::FeedbackFrame fb = r.feedback_now(cam, fs, ox, oy);
      render_gpu_model(*scene, cam, vp, ox, oy, gv);
      scene->render(cam, vp, av);
      const gl::PerPixel G = gl::per_pixel(fb, levels, o.tile_size);
      const gl::Agreement g = gl::agree(gl::per_pixel(gv, levels, o.tile_size), G);
      const gl::Agreement a = gl::agree(gl::per_pixel(av, levels, o.tile_size), G);
      gsum.either += g.either;
      gsum.same += g.same;
      gsum.level_off += g.level_off;
      asum.either += a.either;
      asum.same += a.same;
      asum.level_off += a.level_off;
      gmin = std::min(gmin, g.jaccard);
      amin = std::min(amin, a.jaccard);
      gj += g.jaccard;
      aj += a.jaccard;
      ++i;
    }
    const double n = i > 0 ? static_cast<double>(i) : 1.0;
    const auto pct = [](std::uint64_t a, std::uint64_t b) { return b == 0 ? 100.0 : 100.0 * static_cast<double>(a) / static_cast<double>(b); };
    rows.push_back({{"divisor", d}, {"frames", i}, {"samples", gsum.either},
                    {"gpu_model", {{"same_pct", pct(gsum.same, gsum.either)}, {"level_off_pct", pct(gsum.level_off, gsum.either)},
                                   {"jaccard_min", gmin}, {"jaccard_mean", gj / n}}},
                    {"analytic", {{"same_pct", pct(asum.same, asum.either)}, {"level_off_pct", pct(asum.level_off, asum.either)},
                                  {"jaccard_min", amin}, {"jaccard_mean", aj / n}}}});
    if (!o.json)
      fmt::print("{:7}  {:7}   {:14.3f} %  {:7.3f} %  {:.4f}/{:.4f}   {:12.3f} %  {:7.3f} %  {:.4f}/{:.4f}\n", d, gsum.either,
                 pct(gsum.same, gsum.either), pct(gsum.level_off, gsum.either), gmin, gj / n, pct(asum.same, asum.either),
                 pct(asum.level_off, asum.either), amin, aj / n);
  }
  if (o.json)
    fmt::print("{}\n", nlohmann::json{{"scene", cfg.kind}, {"sampling", o.sampling}, {"image", {wk.w, wk.h}},
                                       {"renderer", ctx.renderer()}, {"gl_errors", ctx.errors()}, {"rows", rows}}
                           .dump(2));
}

void run_replay(const GlOptions& o) {
  const ReplayConfig cfg = load_cli_config(o.configs, o.sets, VtSystem::kName, o.trace == "-");
  if (o.trace.empty()) throw InputError("--trace", "a trace is required");
  if (o.store.empty()) throw InputError("--store", "a tile store is required (vtsim store gen)");
  const Trace trace = load_cli_trace(o.trace, o.allow_repairs);
  check_output("--record-feedback", o.record_feedback);
  check_output("--video", o.video);
  if (!o.frames_png.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(o.frames_png, ec);
    if (ec) throw InputError("--frames-png", o.frames_png + ": " + ec.message());
  }
  const TileStore store = TileStore::open(o.store);
  gl::Context ctx(warn);
  gl::GlReplayOptions go;
  go.sampling = sampling_of(o.sampling_set ? o.sampling : cfg.view.feedback_sampling);
  go.latency = o.latency_set ? o.latency : cfg.view.feedback_latency;
  go.pace = !o.no_pace;
  go.frames_png = o.frames_png;
  go.png_every = o.png_every;
  go.video = o.video;
  go.record_feedback = o.record_feedback;
  go.warn = warn;
  const gl::GlReplayRun run = gl::run_gl_replay(ctx, cfg, trace, store, go);
  const nlohmann::json& s = run.result.summary;
  if (!o.summary.empty()) write_output(o.summary, s.dump(2) + "\n");
  if (!o.record_feedback.empty() && !o.json)
    fmt::print(stderr, "vtsim: feedback trace {}: {} frames, {} bytes (the GPU's feedback; replay it with `vtsim replay --feedback`)\n",
               o.record_feedback, s["trace"]["frames"].get<int>(), run.feedback_trace_bytes);
  if (!o.video.empty() && !o.json) fmt::print(stderr, "vtsim: video {}: {} frames\n", o.video, run.video_frames);
  if (!o.frames_csv.empty()) write_output_via(o.frames_csv, [&](const std::string& p) { run.result.metrics.write_frames_csv(p); });
  if (o.json) {
    fmt::print("{}\n", s.dump(2));
    return;
  }
  const nlohmann::json& pop = s["popin"];
  fmt::print("{} ({}): {} frames in {:.2f} s ({:.1f} frames/s); {} tiles uploaded ({} {} copied to the GPU, {:.2f} ms of GPU upload time over {} timed frames); "
             "{} GL errors{}\n",
             ctx.renderer(), ctx.version(), s["trace"]["frames"].get<int>(), run.seconds, s["gl"]["frames_per_s"].get<double>(),
             run.sink_uploads, run.gpu_copies, s["gl"].contains("clip_stack_consistent") ? "tiles" : "pages", s["gl"]["upload_gpu_ms_total"].get<double>(), s["gl"]["upload_timed_frames"].get<std::uint64_t>(),
             ctx.errors(), s["gl"].contains("clip_stack_consistent") && !run.clip_consistent ? "; the clip stack disagrees with the runtime's clipmap" : "");
  fmt::print("popin: {}\nlatency_ms: {}\n", pop.dump(), s["latency_ms"].dump());
}

#else

void run_replay(const GlOptions&) {
  throw InputError("gl", "this vtsim was built without libepoxy (Debian: libepoxy-dev libegl-dev); rebuild with it");
}
void run_render(const GlOptions&) {
  throw InputError("gl", "this vtsim was built without libepoxy (Debian: libepoxy-dev libegl-dev); rebuild with it");
}
void run_check(const GlOptions& o) { run_render(o); }

#endif

void add_common(CLI::App* cmd, const std::shared_ptr<GlOptions>& opt) {
  cmd->add_option("--scene", opt->scene, "plane | heightfield | town | mesh")->capture_default_str();
  cmd->add_option("--file", opt->file, "scene file (heightfield image, mesh)");
  cmd->add_option("--mesh-unit", opt->mesh_unit_m, "mesh (assimp): metres per file unit; Quake 3: 0.0254")->capture_default_str();
  cmd->add_option("--seed", opt->seed, "generated heightfield / town seed")->capture_default_str();
  cmd->add_option("--noise-posts", opt->noise_posts, "generated heightfield posts a side")->capture_default_str();
  cmd->add_option("--shift", opt->shift_m, "move the world and the camera by (shift, shift, 0) m (far-from-origin check)")
      ->capture_default_str();
  cmd->add_option("--trace", opt->trace, "camera trace")->required();
  cmd->add_flag("--allow-repairs", opt->allow_repairs, kAllowRepairsHelp);
  cmd->add_option("--size", opt->size, "image WxH (default: the trace's)");
  cmd->add_option("--lod-bias", opt->lod_bias, "added to every LOD (the feedback pass adds -log2(divisor))")->capture_default_str();
  cmd->add_option("--aniso", opt->aniso, "anisotropic LOD with this max ratio (0: isotropic)")->capture_default_str();
  cmd->add_option("--sampling", opt->sampling, "pixel of each feedback tile: middle | sequence")->capture_default_str();
  cmd->add_option("--frames", opt->frames, "at most this many frames (0: all)")->capture_default_str();
  cmd->add_option("--every", opt->every, "every Nth trace frame")->capture_default_str();
  cmd->add_option("--tile-size", opt->tile_size, "tile payload, texels")->capture_default_str()->check(CLI::Range(1, 1 << 20));
  cmd->add_option("--latency", opt->latency, "feedback read back this many frames late")->capture_default_str();
  cmd->add_flag("--json", opt->json, "print the results as JSON");
}

}  // namespace gl_cmd

void register_gl_commands(CLI::App& app) {
  auto* gl = app.add_subcommand("gl", "Headless OpenGL 4.5 reference client (EGL; docs/gpu.md)");
  gl->require_subcommand(1);
  auto ro = std::make_shared<gl_cmd::GlOptions>();
  auto* render = gl->add_subcommand("render", "Draw a scene along a trace on the GPU: main pass, feedback pass read back k frames late");
  gl_cmd::add_common(render, ro);
  render->add_option("--divisor", ro->divisor, "feedback buffer = image / divisor")->capture_default_str();
  render->add_option("--frames-png", ro->frames_png, "write the main pass of every --png-every-th frame here");
  render->add_option("--png-every", ro->png_every, "frames between PNGs")->capture_default_str();
  render->callback([ro]() { gl_cmd::run_render(*ro); });
  auto co = std::make_shared<gl_cmd::GlOptions>();
  auto* check = gl->add_subcommand("check", "Compare the GPU's feedback with the simulator's GPU model and analytic model, per pixel and per frame");
  gl_cmd::add_common(check, co);
  check->add_option("--divisors", co->divisors, "comma-separated divisors")->capture_default_str();
  check->callback([co]() { gl_cmd::run_check(*co); });
  auto po = std::make_shared<gl_cmd::GlOptions>();
  auto* rep = gl->add_subcommand("replay", "Stream a virtual texture or a clipmap (run.system) from a tile store through the streaming runtime on "
                                           "the GPU, real clock; "
                                           "the summary and per-frame CSV of `vtsim replay`");
  rep->add_option("--trace,-t", po->trace, "camera trace")->required();
  add_config_options(rep, po->configs, po->sets, " (run.system vt, the default here, or clipmap)");
  rep->add_option("--store", po->store, "tile store (vtsim store gen) matching the config's texture")->required();
  rep->add_option("--summary", po->summary, "write the summary JSON here (- for stdout)");
  rep->add_option("--frames", po->frames_csv, "write one CSV row per frame here (- for stdout)");
  rep->add_option_function<std::string>(
      "--sampling", [po](const std::string& s) { po->sampling = s, po->sampling_set = true; },
      "pixel of each feedback tile: middle | sequence (default: view.feedback_sampling, middle)");
  rep->add_option_function<int>(
      "--latency", [po](int k) { po->latency = k, po->latency_set = true; },
      "feedback read back this many frames late (default: view.feedback_latency, 0; engines: 2-3)");
  rep->add_option("--frames-png", po->frames_png, "write the main pass of every --png-every-th frame here");
  rep->add_option("--png-every", po->png_every, "frames between PNGs")->capture_default_str();
  rep->add_option("--video", po->video, "write a video of every frame here (needs ffmpeg; .mp4, .mkv, .mov or .webm)");
  rep->add_option("--record-feedback", po->record_feedback,
                  "write the GPU feedback each frame acted on as a feedback trace (docs/feedback.md)");
  rep->add_flag("--no-pace", po->no_pace, "start each frame as soon as the last ends (default: at its trace time)");
  rep->add_flag("--allow-repairs", po->allow_repairs, kAllowRepairsHelp);
  rep->add_flag("--json", po->json, "print the summary JSON");
  rep->callback([po]() { gl_cmd::run_replay(*po); });
  register_gl_calibrate_command(*gl);
}

}  // namespace vtsim::cli
