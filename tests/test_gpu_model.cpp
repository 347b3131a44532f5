// The GPU feedback model (sim/view/gpu_model.h): the tile pixel sequence, and the model against
// closed forms where a GPU's finite differences are exact (texel coordinates affine on screen).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <set>
#include <utility>

#include "core/camera.h"
#include "sim/view/gpu_model.h"
#include "sim/view/scene.h"

using namespace vtsim;

TEST_CASE("gpu model: the middle pixel, and a sequence visiting every pixel of the tile once per divisor^2 frames") {
  int ox = -1, oy = -1;
  feedback_tile_offset(FeedbackSampling::middle, 17, 8, ox, oy);
  CHECK(ox == 4);
  CHECK(oy == 4);
  for (const int d : {2, 5, 8, 16}) {
    std::set<std::pair<int, int>> seen;
    for (long long f = 0; f < static_cast<long long>(d) * d; ++f) {
      feedback_tile_offset(FeedbackSampling::sequence, f, d, ox, oy);
      REQUIRE(ox >= 0);
      REQUIRE(ox < d);
      REQUIRE(oy >= 0);
      REQUIRE(oy < d);
      seen.insert({ox, oy});
    }
    CHECK(seen.size() == static_cast<std::size_t>(d) * static_cast<std::size_t>(d));
    int nx = 0, ny = 0;
    feedback_tile_offset(FeedbackSampling::sequence, static_cast<long long>(d) * d + 3, d, nx, ny);
    feedback_tile_offset(FeedbackSampling::sequence, 3, d, ox, oy);
    CHECK(std::make_pair(nx, ny) == std::make_pair(ox, oy));  // periodic
  }
}

TEST_CASE("gpu model: looking straight down on the plane, quad differences are the analytic derivatives") {
  // Texel coordinates are affine in screen space when the image plane is parallel to the ground:
  // the GPU's finite differences are exact, so the model's LOD at divisor d is the analytic
  // full-resolution LOD (d times the footprint, minus log2 d), and the samples are the same.
  SceneConfig cfg;
  cfg.kind = "plane";
  const auto scene = make_scene(cfg);
  // 640×352: whole 16-pixel tiles (a partial tile's model sample lies beyond the image).
  const Camera cam = make_camera(pose_from_angles({4096.3, 4095.7, 40.0}, 30.0, -90.0), 640, 352);
  for (const int d : {1, 8, 16}) {
    ViewParams p;
    p.divisor = d;
    ViewBuffer model, analytic;
    render_gpu_model(*scene, cam, p, d / 2, d / 2, model);
    scene->render(cam, p, analytic);
    REQUIRE(model.samples.size() == analytic.samples.size());
    REQUIRE(!model.samples.empty());
    for (std::size_t i = 0; i < model.samples.size(); ++i) {
      const ViewSample& a = model.samples[i];
      const ViewSample& b = analytic.samples[i];
      CHECK(a.pixel == b.pixel);
      CHECK(a.u == b.u);
      CHECK(a.v == b.v);
      CHECK(std::abs(a.lod - b.lod) < 1e-4f);
    }
  }
}

TEST_CASE("gpu model: at a slant the quad differences differ from the analytic footprint, the bias is -log2(divisor)") {
  SceneConfig cfg;
  cfg.kind = "plane";
  const auto scene = make_scene(cfg);
  const Camera cam = make_camera(pose_from_angles({4096.0, 4096.0, 1.7}, 0.0, -10.0), 640, 360);
  ViewParams p;
  p.divisor = 8;
  ViewBuffer model, analytic;
  render_gpu_model(*scene, cam, p, 4, 4, model);
  scene->render(cam, p, analytic);
  REQUIRE(model.samples.size() == analytic.samples.size());
  double max_diff = 0.0, mean_abs = 0.0;
  for (std::size_t i = 0; i < model.samples.size(); ++i) {
    CHECK(model.samples[i].u == analytic.samples[i].u);
    const double diff = std::abs(static_cast<double>(model.samples[i].lod - analytic.samples[i].lod));
    max_diff = std::max(max_diff, diff);
    mean_abs += diff;
  }
  mean_abs /= static_cast<double>(model.samples.size());
  // Differences over 8 pixels of a perspective ground: the partner of an even row lies nearer,
  // of an odd row farther, so the footprints differ from the derivative at the pixel, by a
  // fraction of a level on average (up to about a level towards the horizon).
  CHECK(max_diff > 0.02);
  CHECK(max_diff < 2.0);
  CHECK(mean_abs < 0.2);
  // A tile offset outside the tile is refused.
  CHECK_THROWS_AS(render_gpu_model(*scene, cam, p, 8, 0, model), std::invalid_argument);
}
