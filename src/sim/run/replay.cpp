#include "sim/run/replay.h"

#include <fmt/format.h>

#include <chrono>
#include <ctime>

#include "core/error.h"
#include "sim/view/scene.h"

namespace vtsim {

SceneConfig scene_config_of(const ReplayConfig& cfg) {
  SceneConfig sc = cfg.scene;  // kind, file, height scale, mesh_* (the scene.* keys)
  sc.texels_per_m = cfg.texture.texels_per_m;
  sc.size_x_m = static_cast<double>(cfg.texture.width) / cfg.texture.texels_per_m;
  sc.size_y_m = static_cast<double>(cfg.texture.height) / cfg.texture.texels_per_m;
  sc.origin_x_m = cfg.texture.origin_x_m;
  sc.origin_y_m = cfg.texture.origin_y_m;
  return sc;
}

std::unique_ptr<IScene> make_scene_from_config(const ReplayConfig& cfg) {
  auto scene = make_scene(scene_config_of(cfg));
  if (cfg.view.lod_model == "gpu") scene = make_gpu_model_scene(std::move(scene));
  const TextureExtent e = scene->texture();
  if (e.width != cfg.texture.width || e.height != cfg.texture.height)
    throw InputError("config", fmt::format("field 'texture.width': the scene's texture is {}×{} texels, the config "
                                           "says {}×{} (texture size / texels_per_m must be exact)",
                                           e.width, e.height, cfg.texture.width, cfg.texture.height));
  return scene;
}

namespace {

// CPU time of the calling thread, seconds: the frame loop's own work, without the feedback that
// render-ahead workers render.
double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

}  // namespace

ReplayResult run_replay(const ReplayConfig& cfg, const Trace& trace, const IScene& scene, const ReplayEnv& env) {
  const auto wall0 = std::chrono::steady_clock::now();
  const double cpu0 = thread_cpu_s();
  const FramePlan plan = plan_frames(cfg, trace);
  SystemRun run(cfg, plan, scene, env);
  const int threads = ViewStream::resolve_threads(cfg, plan, env.executor != nullptr);
  // Before any frame a system without span support reads samples (uses_spans).
  ViewStream view(cfg, plan, scene, run.block_shift(), !run.system().uses_spans(), threads);
  if (env.pace) view.warm_up(run.keep_samples());
  auto last_progress = wall0;
  for (int f = 0; f < plan.frames; ++f) {
    const Ticks target = plan.target(f);
    run.begin_frame(f, env.pace ? env.pace(f, target) : target);
    const FrameView& fv = view.frame(f, run.keep_samples());
    if (env.on_view) env.on_view(plan, fv);
    run.step(fv);
    if (env.progress) {
      const auto t = std::chrono::steady_clock::now();
      if (t - last_progress > std::chrono::seconds(1)) {
        env.progress(f, plan.frames);
        last_progress = t;
      }
    }
  }
  RunCost cost;
  cost.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  cost.loop_cpu_s = thread_cpu_s() - cpu0;
  cost.render_threads = threads;
  return run.summarize(cost);
}

RecordedReplay record_accesses(const ReplayConfig& cfg, const Trace& trace, const IScene& scene) {
  RecordedReplay r;
  ReplayEnv env;
  env.accesses = &r.accesses;
  r.result = run_replay(cfg, trace, scene, env);
  return r;
}

RecordedReplay record_accesses(const ReplayConfig& cfg, const Trace& trace) {
  const std::unique_ptr<IScene> scene = make_scene_from_config(cfg);
  return record_accesses(cfg, trace, *scene);
}

}  // namespace vtsim
