// Render-ahead (src/sim/run/render_ahead.h): workers render the frames the loop will need; the buffers
// equal the loop's own renders exactly, in order, and the replay's metrics do not depend on the
// thread count; errors reach the consumer at their frame; shutdown never hangs.
#include <doctest/doctest.h>

#include <atomic>
#include <cstring>
#include <stdexcept>

#include "core/camera.h"
#include "sim/run/render_ahead.h"
#include "sim/run/replay.h"
#include "sim/view/scene.h"
#include "sim/trace/trace_gen.h"
#include "trace_test_util.h"

// Threaded code: also run by the TSan variant of scripts/test.sh (ctest -L threads).
TEST_SUITE_BEGIN("threads");

using namespace vtsim;

namespace {

bool same_spans(const SpanBuffer& a, const SpanBuffer& b) {
  if (a.spans.size() != b.spans.size() || a.samples != b.samples || a.width != b.width || a.height != b.height ||
      a.has_samples != b.has_samples || a.view.samples.size() != b.view.samples.size())
    return false;
  for (std::size_t i = 0; i < a.spans.size(); ++i) {
    const ViewSpan &x = a.spans[i], &y = b.spans[i];
    if (x.u_lo != y.u_lo || x.u_hi != y.u_hi || x.v_lo != y.v_lo || x.v_hi != y.v_hi || x.pixel != y.pixel ||
        x.count != y.count || x.first != y.first || x.level != y.level)
      return false;
  }
  for (std::size_t i = 0; i < a.view.samples.size(); ++i) {
    const ViewSample &x = a.view.samples[i], &y = b.view.samples[i];
    if (x.u != y.u || x.v != y.v || x.pixel != y.pixel || std::memcmp(&x.lod, &y.lod, sizeof x.lod) != 0) return false;
  }
  return a.counters.sky == b.counters.sky && a.counters.clipped == b.counters.clipped &&
         a.counters.backfacing == b.counters.backfacing && a.counters.outside_texture == b.counters.outside_texture;
}

Camera town_camera(std::size_t j) {
  // A walk along the first street, turning: every frame a different view.
  const double t = static_cast<double>(j);
  return make_camera(pose_from_angles({30.0 + 0.5 * t, 8.0, 1.7}, 7.0 * t, -15.0), 320, 180);
}

// Throws for job `bad`; renders nothing otherwise (counts the renders).
class FailingScene final : public IScene {
 public:
  explicit FailingScene(double bad_x) : bad_x_(bad_x) {}
  TextureExtent texture() const override { return {1024, 1024}; }
  void render(const Camera& cam, const ViewParams&, ViewBuffer& out) const override {
    renders.fetch_add(1);
    out.samples.clear();
    if (cam.pos_m.x == bad_x_) throw std::runtime_error("render failed");
  }
  mutable std::atomic<int> renders{0};

 private:
  double bad_x_;
};

ReplayResult town_replay(const Trace& t, std::vector<std::string> sets, int threads) {
  sets.push_back("scene.kind=town");
  sets.push_back("view.render_threads=" + std::to_string(threads));
  const ReplayConfig cfg = load_replay_config("", sets, "vt");
  auto scene = make_scene_from_config(cfg);
  return run_replay(cfg, t, *scene);
}

}  // namespace

TEST_CASE("render-ahead: every job's buffers equal the scene's own render, in order, for 1-3 workers") {
  SceneConfig sc;
  sc.kind = "town";
  const auto scene = make_scene(sc);
  ViewParams vp, pp;
  pp.divisor = 3;
  SpanBuffer ref, ref_p;
  ref.block_shift = ref_p.block_shift = 7;
  ref.keep_samples = ref_p.keep_samples = true;
  for (int threads = 1; threads <= 3; ++threads) {
    CAPTURE(threads);
    constexpr std::size_t kJobs = 40;
    RenderAhead ahead(*scene, kJobs, town_camera, vp, &pp, 7, true, threads);
    for (std::size_t j = 0; j < kJobs; ++j) {
      CAPTURE(j);
      const RenderAhead::Buffers& b = ahead.next();
      scene->render_spans(town_camera(j), vp, ref);
      scene->render_spans(town_camera(j), pp, ref_p);
      REQUIRE(ref.samples > 0);
      CHECK(same_spans(b.feedback, ref));
      CHECK(same_spans(b.popin, ref_p));
    }
    CHECK_THROWS_AS(ahead.next(), std::logic_error);
  }
}

TEST_CASE("render-ahead: keep_samples switched while jobs run — the buffers equal the scene's render either way") {
  SceneConfig sc;
  sc.kind = "town";
  const auto scene = make_scene(sc);
  const ViewParams vp;
  SpanBuffer ref;
  ref.block_shift = 7;
  constexpr std::size_t kJobs = 30;
  RenderAhead ahead(*scene, kJobs, town_camera, vp, nullptr, 7, false, 2);
  std::size_t with = 0, without = 0;
  for (std::size_t j = 0; j < kJobs; ++j) {
    CAPTURE(j);
    ahead.set_keep_samples(j % 10 >= 5);  // jobs already started keep the old setting
    RenderAhead::Buffers& b = ahead.next();
    ref.keep_samples = b.feedback.has_samples;
    scene->render_spans(town_camera(j), vp, ref);
    CHECK(same_spans(b.feedback, ref));
    (b.feedback.has_samples ? with : without) += 1;
    materialise_samples(b.feedback);  // the consumer completes a held buffer
    ref.keep_samples = true;
    scene->render_spans(town_camera(j), vp, ref);
    CHECK(same_spans(b.feedback, ref));
  }
  CHECK(with > 5);
  CHECK(without > 5);
}

TEST_CASE("render-ahead: a replay's summary and per-frame CSV do not depend on the thread count") {
  // A walk with a pause (equal poses: reused buffers), feedback every 2nd frame, a separate pop-in
  // buffer: every path that decides which frames render.
  TraceGenParams g = default_gen_params("walk");
  g.duration_s = 3.0;
  g.start_m = {30.0, 8.0};
  Trace t = generate_trace(g);
  test::hold_last_pose(t, 60);
  const test::ScratchDir dir;
  // The second set: a pool small enough for Unreal's residency bias, whose frames the system
  // reads per sample (wants_samples: rendered with samples, or expanded from spans).
  for (const std::vector<std::string>& sets :
       {std::vector<std::string>{"view.feedback_every=2", "view.popin_divisor=4", "vt.pool_pages=200"},
        std::vector<std::string>{"vt.pool_pages=48", "throttle.policy=unreal_bias", "texture.border=4"}}) {
    std::string csv0;
    nlohmann::json sum0;
    for (const int threads : {0, 1, 3}) {
      CAPTURE(threads);
      ReplayResult r = town_replay(t, sets, threads);
      const std::string path = dir.file("frames_" + std::to_string(threads) + ".csv");
      r.metrics.write_frames_csv(path);
      CHECK(r.summary["run"]["render_threads"].get<int>() == threads);
      r.summary.erase("run");
      r.summary["config"].erase("view.render_threads");  // the one key that differs: results must not
      if (threads == 0) {
        csv0 = test::slurp(path);
        sum0 = r.summary;
        REQUIRE(r.summary["popin"]["measured_frames"].get<int>() > 50);
        if (sets[1] == "throttle.policy=unreal_bias") REQUIRE(r.summary["throttle"]["changes"].get<int>() > 50);
        continue;
      }
      CHECK(test::slurp(path) == csv0);
      CHECK(r.summary.dump() == sum0.dump());
    }
  }
}

TEST_CASE("render-ahead: a render error reaches the consumer at its job, and shutdown with work pending does not hang") {
  const FailingScene scene(5.0);  // job 5's camera is at x = 5
  const auto cam = [](std::size_t j) {
    return make_camera(pose_from_angles({static_cast<double>(j), 0.0, 10.0}, 0.0, -30.0), 64, 48);
  };
  {
    RenderAhead ahead(scene, 100, cam, ViewParams{}, nullptr, 7, true, 2);
    for (int j = 0; j < 5; ++j) CHECK_NOTHROW(ahead.next());
    CHECK_THROWS_WITH_AS(ahead.next(), "render failed", std::runtime_error);
    CHECK_NOTHROW(ahead.next());  // later jobs still render
  }  // destroyed with ~90 jobs not taken: the workers stop after their current render
  CHECK(scene.renders.load() < 100);
  {
    RenderAhead idle(scene, 1000, cam, ViewParams{}, nullptr, 7, true, 3);  // nothing taken at all
  }
  CHECK_THROWS_AS(RenderAhead(scene, 1, cam, ViewParams{}, nullptr, 7, true, 0), std::invalid_argument);
  CHECK(RenderAhead::resolve_threads(0) == 0);
  CHECK(RenderAhead::resolve_threads(5) == 5);
  const int autos = RenderAhead::resolve_threads(-1);
  CHECK((autos == 0 || (autos >= 2 && autos <= 8)));
  // The ring's memory: 1920×1080 at divisor 8 is 32,400 pixels (2.3 MB a slot at most); at
  // divisor 1 ~150 MB, so 512 MiB holds 3 slots: 1 thread.
  ViewParams d8, d1;
  d1.divisor = 1;
  const std::uint64_t b8 = RenderAhead::slot_bytes(1920, 1080, d8, nullptr);
  const std::uint64_t b1 = RenderAhead::slot_bytes(1920, 1080, d1, nullptr);
  CHECK(b8 == 32400 * (sizeof(ViewSample) + sizeof(ViewSpan)));
  CHECK(RenderAhead::slot_bytes(1920, 1080, d8, &d1) == b8 + b1);
  CHECK(RenderAhead::cap_threads(8, b8) == 8);
  CHECK(RenderAhead::cap_threads(8, b1) == 1);
  CHECK(RenderAhead::cap_threads(0, b1) == 0);
  CHECK(RenderAhead::cap_threads(64, RenderAhead::kRingBytes / 10) == 8);
}

TEST_SUITE_END();
