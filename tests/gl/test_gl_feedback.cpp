// The GL reference client against the simulator (docs/gpu.md): the context and its KHR_debug
// channel, the GPU model's per-pixel agreement with the GPU's feedback pass on the plane, a
// heightfield and the town at divisors 1, 8 and 16, and the same feedback and images 10^7 m from
// the origin.
#include <doctest/doctest.h>

#include <epoxy/gl.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "core/camera.h"
#include "gl/gl_check.h"
#include "gl/gl_context.h"
#include "gl/gl_renderer.h"
#include "gl_test_util.h"
#include "sim/view/gpu_model.h"
#include "sim/view/scene.h"

namespace {

using namespace vtsim;

gl::Context& context() { return gl_test::shared().ctx; }

// Agreement of the GPU model and (for the report) the analytic model with the GPU on `cams`.
struct Tally {
  gl::Agreement gpu, analytic;
  double min_jaccard = 1.0;
};

Tally tally(const SceneConfig& cfg, const std::vector<Camera>& cams, int divisor) {
  const auto scene = make_scene(cfg);
  gl::Renderer r(context(), cfg);
  const int levels = mip_level_count(r.texture());
  gl::FeedbackSettings fs;
  fs.divisor = divisor;
  ViewParams vp;
  vp.divisor = divisor;
  Tally t;
  ViewBuffer gv, av;
  for (const Camera& cam : cams) {
    const int o = divisor / 2;
    const gl::FeedbackFrame fb = r.feedback_now(cam, fs, o, o);
    render_gpu_model(*scene, cam, vp, o, o, gv);
    scene->render(cam, vp, av);
    const gl::PerPixel G = gl::per_pixel(fb, levels, 128);
    const gl::Agreement g = gl::agree(gl::per_pixel(gv, levels, 128), G);
    const gl::Agreement a = gl::agree(gl::per_pixel(av, levels, 128), G);
    t.gpu.either += g.either;
    t.gpu.same += g.same;
    t.gpu.level_off += g.level_off;
    t.analytic.either += a.either;
    t.analytic.same += a.same;
    t.min_jaccard = std::min(t.min_jaccard, g.jaccard);
  }
  return t;
}

std::vector<Camera> cameras(const glm::dvec3& base, int w, int h) {
  std::vector<Camera> c;
  c.push_back(make_camera(pose_from_angles(base, 30.0, -12.0), w, h));
  c.push_back(make_camera(pose_from_angles(base + glm::dvec3(17.3, -5.1, 0.0), 200.0, -25.0, 7.0), w, h));
  return c;
}

}  // namespace

TEST_CASE("gl: an OpenGL 4.5 core context through EGL, GL errors on the warning channel") {
  gl::Context& ctx = context();
  std::vector<std::string>& seen = gl_test::shared().warnings;
  CHECK(!ctx.renderer().empty());
  CHECK(ctx.version().rfind("4.", 0) == 0);
  const int before = ctx.errors();
  const std::size_t n = seen.size();
  glBindBuffer(GL_ARRAY_BUFFER, 987654);  // a name never generated: GL_INVALID_OPERATION in core
  CHECK(ctx.errors() == before + 1);
  REQUIRE(seen.size() == n + 1);
  CHECK(seen.back().find("gl: error") == 0);
  seen.clear();
}

TEST_CASE("gl: the GPU model agrees with the GPU's feedback on the plane, heightfield and town") {
  struct Case {
    const char* kind;
    glm::dvec3 pos;
  };
  for (const Case& c : {Case{"plane", {4096.0, 4096.0, 1.7}}, Case{"heightfield", {300.0, 400.0, 160.0}},
                        Case{"town", {8.0, 8.0, 1.7}}}) {
    SceneConfig cfg;
    cfg.kind = c.kind;
    cfg.noise_posts = 129;  // 1 km of hills: a quick build
    for (const int d : {1, 8, 16}) {
      // Divisor 1 at a quarter of the pixels (the model ray-casts every one on the CPU).
      const std::vector<Camera> cams = d == 1 ? cameras(c.pos, 480, 270) : cameras(c.pos, 1280, 720);
      const Tally t = tally(cfg, cams, d);
      INFO(std::string(c.kind), " divisor ", d, ": gpu model ", 100.0 * t.gpu.same_fraction(), " % of ", t.gpu.either,
           " samples, analytic ", 100.0 * t.analytic.same_fraction(), " %, min Jaccard ", t.min_jaccard);
      CHECK(t.gpu.either > 100);
      CHECK(t.gpu.same_fraction() >= 0.999);
      CHECK(t.min_jaccard >= 0.995);
    }
  }
}

TEST_CASE("gl: 10^7 m from the origin, the same feedback and the same image") {
  for (const char* kind : {"plane", "town"}) {
    SceneConfig near_cfg;
    near_cfg.kind = kind;
    SceneConfig far_cfg = near_cfg;
    const double shift = 1.0e7;
    far_cfg.origin_x_m += shift;
    far_cfg.origin_y_m += shift;
    const glm::dvec3 pos = std::string(kind) == "plane" ? glm::dvec3(4096.0, 4096.0, 1.7) : glm::dvec3(8.0, 8.0, 1.7);
    const Camera a = make_camera(pose_from_angles(pos, 30.0, -12.0), 640, 360);
    const Camera b = make_camera(pose_from_angles(pos + glm::dvec3(shift, shift, 0.0), 30.0, -12.0), 640, 360);
    gl::FeedbackSettings fs;
    fs.divisor = 8;
    std::vector<std::uint8_t> img[2];
    gl::FeedbackFrame fb[2];
    int w = 0, h = 0;
    {
      gl::Renderer r(context(), near_cfg);
      r.draw_main(a, fs);
      img[0] = r.read_main(w, h);
      fb[0] = r.feedback_now(a, fs, 4, 4);
    }
    {
      gl::Renderer r(context(), far_cfg);
      r.draw_main(b, fs);
      img[1] = r.read_main(w, h);
      fb[1] = r.feedback_now(b, fs, 4, 4);
    }
    INFO(kind);
    REQUIRE(fb[0].px.size() == fb[1].px.size());
    std::size_t same = 0, samples = 0;
    for (std::size_t i = 0; i < fb[0].px.size(); ++i) {
      samples += fb[0].px[i].status == 1;
      same += std::memcmp(&fb[0].px[i], &fb[1].px[i], sizeof(gl::FeedbackTexel)) == 0;
    }
    CHECK(samples > 1000);
    CHECK(same == fb[0].px.size());
    CHECK(img[0] == img[1]);
  }
}
