#include <doctest/doctest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <random>

#include "core/error.h"
#include "sim/scene.h"
#include "sim/scene_mesh.h"
#include "sim/scene_town.h"

using namespace vtsim;

TEST_CASE("town: deterministic / every face owns a disjoint texel rectangle inside the texture") {
  SceneConfig cfg;
  cfg.kind = SceneKind::town;
  const Mesh a = generate_town(cfg);
  const Mesh b = generate_town(cfg);
  CHECK(a.positions == b.positions);
  CHECK(a.uvs == b.uvs);
  cfg.seed = 2;
  CHECK(generate_town(cfg).positions != a.positions);

  const double W = 1 << 20;
  struct Rect {
    double u0, v0, u1, v1;
  };
  std::vector<Rect> rects;
  REQUIRE(a.uvs.size() % 4 == 0);
  REQUIRE(a.tris.size() == a.uvs.size() / 2);
  for (std::size_t q = 0; q < a.uvs.size(); q += 4) {
    Rect r{1e300, 1e300, -1e300, -1e300};
    for (std::size_t k = q; k < q + 4; ++k) {
      r.u0 = std::min(r.u0, a.uvs[k].x * W);
      r.v0 = std::min(r.v0, a.uvs[k].y * W);
      r.u1 = std::max(r.u1, a.uvs[k].x * W);
      r.v1 = std::max(r.v1, a.uvs[k].y * W);
    }
    rects.push_back(r);
  }
  // 17² ground quads + 16² blocks · (4 buildings + 2 walls) · 5 faces.
  CHECK(rects.size() == 17 * 17 + 16 * 16 * 6 * 5);
  int outside = 0, overlaps = 0;
  const std::size_t ground = 17 * 17;
  for (const Rect& r : rects) outside += r.u0 < 0 || r.v0 < 0 || r.u1 > W || r.v1 > W;
  // Ground quads tile [0, S·tpm)² edge to edge (planar mapping); faces must not touch anything.
  std::vector<std::size_t> order(rects.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) { return rects[x].v0 < rects[y].v0; });
  for (std::size_t i = 0; i < order.size(); ++i) {
    const Rect& r = rects[order[i]];
    for (std::size_t j = i + 1; j < order.size() && rects[order[j]].v0 < r.v1; ++j) {
      const Rect& s = rects[order[j]];
      if (order[i] < ground && order[j] < ground) continue;
      overlaps += r.u0 < s.u1 && s.u0 < r.u1 && r.v0 < s.v1 && s.v0 < r.v1;
    }
  }
  CHECK(outside == 0);
  CHECK(overlaps == 0);
}

TEST_CASE("town: renders ground / walls and roofs / bad parameters are rejected") {
  SceneConfig cfg;
  cfg.kind = SceneKind::town;
  const auto town = make_scene(cfg);
  ViewParams vp;
  ViewBuffer vb;
  const double S = town_size_m(cfg);
  town->render(make_camera(pose_from_angles({8, 8, 1.7}, 45, -2), 1920, 1080), vp, vb);
  std::size_t ground = 0, faces = 0;
  int bad = 0;
  for (const ViewSample& s : vb.samples) {
    bad += !std::isfinite(s.lod);
    (static_cast<double>(s.v) < S * 128 ? ground : faces) += 1;
  }
  CHECK(bad == 0);
  CHECK(ground > 1000);
  CHECK(faces > 1000);
  // From above, roofs and streets.
  town->render(make_camera(pose_from_angles({S / 2, S / 2, 300}, 0, -90), 1920, 1080), vp, vb);
  CHECK(vb.samples.size() == 240u * 135u);

  SceneConfig bad_cfg = cfg;
  bad_cfg.town_blocks = 0;
  CHECK_THROWS_AS(generate_town(bad_cfg), InputError);
  bad_cfg = cfg;
  bad_cfg.town_max_height_m = std::nan("");
  CHECK_THROWS_AS(generate_town(bad_cfg), InputError);
  bad_cfg = cfg;
  bad_cfg.town_street_m = 1e9;
  CHECK_THROWS_AS(generate_town(bad_cfg), InputError);
  bad_cfg = cfg;
  bad_cfg.size_x_m = bad_cfg.size_y_m = 1000;  // town (1232 m) larger than the texture's ground
  CHECK_THROWS_AS(generate_town(bad_cfg), InputError);
  bad_cfg = cfg;
  bad_cfg.size_x_m = bad_cfg.size_y_m = 1300;  // the ground fits, the faces do not
  CHECK_THROWS_WITH_AS(generate_town(bad_cfg), doctest::Contains("do not fit"), InputError);
}

TEST_CASE("town: occlusion culling renders exactly what drawing every chunk in index order renders, from any warm start") {
  SceneConfig cfg;
  cfg.kind = SceneKind::town;
  MeshScene culled(generate_town(cfg), scene_texture(cfg)), plain(generate_town(cfg), scene_texture(cfg));
  plain.set_occlusion_culling(false);
  const double S = town_size_m(cfg);
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  ViewBuffer a, b;
  std::size_t samples = 0;
  for (int it = 0; it < 60; ++it) {
    // Mostly eye height in the town (streets, sometimes inside a building or a wall), some from
    // above; any heading; divisors 1–16.
    const double z = it % 6 == 5 ? 30.0 + 300.0 * U(rng) : 0.5 + 2.0 * U(rng);
    const Camera cam = make_camera(pose_from_angles({S * U(rng), S * U(rng), z}, 360.0 * U(rng), -60.0 + 75.0 * U(rng),
                                                    it % 4 == 3 ? 30.0 * U(rng) : 0.0),
                                   640, 360);
    ViewParams vp;
    const int divisors[] = {1, 2, 4, 8, 16};
    vp.divisor = divisors[rng() % 5];
    if (it % 7 == 0) vp.near_m = 3.0;
    culled.render(cam, vp, a);
    plain.render(cam, vp, b);
    CAPTURE(it);
    REQUIRE(a.samples.size() == b.samples.size());
    // The culled render starts from the triangles the previous render on this thread saw (here
    // another camera's); again at the same camera, from its own: the same buffer every time.
    if (it % 5 == 0) {
      ViewBuffer again;
      culled.render(cam, vp, again);
      REQUIRE(again.samples.size() == a.samples.size());
      for (std::size_t i = 0; i < a.samples.size(); ++i)
        REQUIRE((again.samples[i].u == a.samples[i].u && again.samples[i].v == a.samples[i].v &&
                 again.samples[i].pixel == a.samples[i].pixel &&
                 std::bit_cast<std::uint32_t>(again.samples[i].lod) == std::bit_cast<std::uint32_t>(a.samples[i].lod)));
    }
    std::size_t differ = 0;
    for (std::size_t i = 0; i < a.samples.size(); ++i)
      differ += a.samples[i].u != b.samples[i].u || a.samples[i].v != b.samples[i].v ||
                a.samples[i].pixel != b.samples[i].pixel ||
                std::bit_cast<std::uint32_t>(a.samples[i].lod) != std::bit_cast<std::uint32_t>(b.samples[i].lod);
    REQUIRE(differ == 0);
    CHECK(a.counters.sky == b.counters.sky);
    CHECK(a.counters.clipped == b.counters.clipped);
    CHECK(a.counters.backfacing == b.counters.backfacing);
    CHECK(a.counters.outside_texture == b.counters.outside_texture);
    CHECK(a.counters.untextured == b.counters.untextured);
    samples += a.samples.size();
  }
  CHECK(samples > 100000);
}
