// Spans (run-length feedback) against the per-sample reference, exactly: the plane's span
// renderer against spans_from_samples(render()), span aggregation, clipmap span residency and
// span pop-in against their per-sample forms, on many random cameras and clipmap states.
#include <doctest/doctest.h>

#include <bit>
#include <random>
#include <stdexcept>

#include "cache/clipmap.h"
#include "stream/system/feedback.h"
#include "sim/run/popin.h"
#include "sim/view/scene.h"
#include "test_util.h"
#include "view_test_util.h"

using namespace vtsim;

namespace {

using test::same_counters;
using test::same_sample;
using test::same_span;

struct RandomView {
  Camera cam;
  ViewParams vp;
  int block_shift = 7;
};

// Heights from 0.3 m to 5 km, any heading, pitch from straight down to above the horizon, half
// without roll (the hoisted row path), sizes from 64×48 to 1920×1080, divisors 1–16, biases,
// both LOD rules, near/far clips that cut.
RandomView random_view(std::mt19937_64& rng, double cx, double cy) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  RandomView r;
  const double h = 0.3 * std::pow(5000.0 / 0.3, U(rng));
  const double z = U(rng) < 0.05 ? -h : h;  // sometimes below the plane
  const double yaw = 360.0 * U(rng), pitch = -90.0 + 120.0 * U(rng);
  const double roll = U(rng) < 0.5 ? 0.0 : -180.0 + 360.0 * U(rng);
  const double vfov = 20.0 + 100.0 * U(rng);
  const int sizes[][2] = {{64, 48}, {320, 240}, {640, 480}, {1280, 720}, {1920, 1080}, {333, 171}};
  const auto& sz = sizes[rng() % 6];
  r.cam = make_camera(pose_from_angles({cx + 300.0 * (U(rng) - 0.5), cy + 300.0 * (U(rng) - 0.5), z}, yaw, pitch, roll, vfov),
                      sz[0], sz[1]);
  const int divisors[] = {1, 2, 3, 4, 8, 16};
  r.vp.divisor = divisors[rng() % 6];
  const float biases[] = {0.0f, 0.0f, 0.5f, -1.25f, 2.0f};
  r.vp.lod_bias = biases[rng() % 5];
  r.vp.anisotropic = U(rng) < 0.3;
  r.vp.max_aniso = U(rng) < 0.5 ? 16.0f : 4.0f;
  if (U(rng) < 0.2) r.vp.near_m = 2.0 + 20.0 * U(rng);
  if (U(rng) < 0.2) r.vp.far_m = r.vp.near_m + 50.0 + 2000.0 * U(rng);
  const int shifts[] = {7, 7, 0, 3, 6, 10};
  r.block_shift = shifts[rng() % 6];
  return r;
}

std::unique_ptr<IScene> plane_scene(double origin_x = 0.0, double origin_y = 0.0) {
  SceneConfig cfg;
  cfg.kind = "plane";
  cfg.origin_x_m = origin_x;
  cfg.origin_y_m = origin_y;
  return make_scene(cfg);
}

// render_spans of `sc` against spans_from_samples(render()) field for field, and every span's
// expansion against render()'s samples. Returns the spans' count.
std::size_t check_spans_exact(const IScene& sc, const RandomView& rv, ViewBuffer& vb, SpanBuffer& sb) {
  const int levels = mip_level_count(sc.texture());
  std::vector<ViewSpan> ref;
  std::vector<ViewSample> expanded;
  sc.render(rv.cam, rv.vp, vb);
  spans_from_samples(vb, levels, rv.block_shift, ref);
  sb.block_shift = rv.block_shift;
  sb.keep_samples = false;
  sc.render_spans(rv.cam, rv.vp, sb);
  REQUIRE_FALSE(sb.has_samples);
  REQUIRE(sb.width == vb.width);
  REQUIRE(sb.height == vb.height);
  REQUIRE(sb.levels == levels);
  REQUIRE(sb.samples == vb.samples.size());
  REQUIRE(same_counters(sb.counters, vb.counters));
  REQUIRE(sb.spans.size() == ref.size());
  std::size_t differ = 0;
  for (std::size_t i = 0; i < ref.size(); ++i) differ += !same_span(sb.spans[i], ref[i]);
  REQUIRE(differ == 0);
  // Expansion re-renders exactly render()'s samples.
  std::size_t bad = 0;
  for (const ViewSpan& s : sb.spans) {
    expanded.clear();
    expand_span(sb, s, expanded);
    REQUIRE(expanded.size() == s.count);
    for (std::uint32_t k = 0; k < s.count; ++k) bad += !same_sample(expanded[k], vb.samples[s.first + k]);
  }
  REQUIRE(bad == 0);
  // All spans at once (adjacent spans in one scene call), then materialised in place.
  expanded.clear();
  expand_spans(sb, 0, sb.spans.size(), expanded);
  REQUIRE(expanded.size() == vb.samples.size());
  for (std::size_t k = 0; k < expanded.size(); ++k) bad += !same_sample(expanded[k], vb.samples[k]);
  REQUIRE(bad == 0);
  materialise_samples(sb);
  REQUIRE(sb.has_samples);
  REQUIRE(sb.view.samples.size() == vb.samples.size());
  for (std::size_t k = 0; k < expanded.size(); ++k) bad += !same_sample(sb.view.samples[k], vb.samples[k]);
  REQUIRE(bad == 0);
  return ref.size();
}

}  // namespace

TEST_CASE("plane render_spans equals spans_from_samples(render) exactly on random cameras") {
  std::mt19937_64 rng(20240601);
  auto scene = plane_scene();
  const auto far_scene = plane_scene(1.0e7, -1.0e7);
  ViewBuffer vb;
  SpanBuffer sb;
  std::size_t total_spans = 0, total_samples = 0;
  const int runs = vtsim::test::property_runs(250);
  for (int it = 0; it < runs; ++it) {
    const bool far = it % 5 == 4;  // texture origin at (1e7 m, −1e7 m)
    const IScene& sc = far ? *far_scene : *scene;
    const RandomView rv = random_view(rng, far ? 1.0e7 + 4096.0 : 4096.0, far ? -1.0e7 + 4096.0 : 4096.0);
    CAPTURE(it);
    total_spans += check_spans_exact(sc, rv, vb, sb);
    total_samples += vb.samples.size();
  }
  // The cameras exercise the structure: many spans, most of them longer than one sample.
  CHECK(total_spans > 5000u * static_cast<unsigned>(runs) / 250u);
  CHECK(total_samples > 4 * total_spans);
}

// The mesh's span renderer (scene_mesh.cpp) over the test town: random views from street level to
// 5 km (walls, roofs, back faces, near and far clips, the texture's edge) and walking cameras one
// after another (the warm start's case). A camera inside or under the town included.
TEST_CASE("town render_spans equals spans_from_samples(render) exactly on random cameras") {
  std::mt19937_64 rng(20261202);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  SceneConfig cfg;
  cfg.kind = "town";
  const auto scene = make_scene(cfg);
  ViewBuffer vb;
  SpanBuffer sb;
  std::size_t total_spans = 0, total_samples = 0;
  // All 150 views under the sanitizers too: the first quarter of them has fewer samples per span
  // (1.88 M samples in 0.87 M spans: 2.2 a span), below the ratio of 3 this case checks.
  for (int it = 0; it < 150; ++it) {
    RandomView rv = random_view(rng, -50.0 + 1100.0 * U(rng), -50.0 + 1100.0 * U(rng));
    if (it % 2 == 0) {
      rv.cam = make_camera(pose_from_angles({30.0 + 5.0 * U(rng), 8.0 + 200.0 * U(rng), 1.7}, 360.0 * U(rng),
                                            -30.0 + 35.0 * U(rng)),
                           1920, 1080);
      rv.vp.divisor = it % 4 == 0 ? 8 : 4;
    }
    CAPTURE(it);
    total_spans += check_spans_exact(*scene, rv, vb, sb);
    total_samples += vb.samples.size();
  }
  CHECK(total_spans > 5000);
  CHECK(total_samples > 3 * total_spans);
}

// The plane caches the level runs of rows without roll for a camera that only translates
// (scene_plane.cpp, FlatRuns): the first frame of an orientation renders column by column, the
// second builds the runs, later ones use them. Every frame must still equal the reference; the
// two buffers alternate as a replay's feedback and pop-in buffers do.
TEST_CASE("plane render_spans on translating cameras (cached level runs) equals the reference exactly") {
  std::mt19937_64 rng(20261122);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  auto scene = plane_scene();
  const auto far_scene = plane_scene(1.0e7, -1.0e7);
  const int levels = mip_level_count(scene->texture());
  ViewBuffer vb;
  SpanBuffer sb[2];
  std::vector<ViewSpan> ref;
  std::size_t total_spans = 0, flat_views = 0;
  const int runs = vtsim::test::property_runs(120);
  for (int it = 0; it < runs; ++it) {
    const bool far = it % 5 == 4;
    const IScene& sc = far ? *far_scene : *scene;
    RandomView rv[2] = {random_view(rng, far ? 1.0e7 + 4096.0 : 4096.0, far ? -1.0e7 + 4096.0 : 4096.0), {}};
    if (it % 3 == 0) rv[0].cam = make_camera(pose_from_angles({4096.0 + 100.0 * U(rng), 4096.0, 1.7}, 360.0 * U(rng),
                                                              -15.0, 0.0, 60.0), 1920, 1080);
    if (it % 7 == 0) rv[0].cam.pos_m = {-50.0 * U(rng), 8192.0 + 50.0 * U(rng), rv[0].cam.pos_m.z};  // off a corner
    // A level camera's left vector is horizontal up to the rounding of its quaternion; make it
    // exactly so (the path without roll) for most views.
    if (U(rng) < 0.7 && std::fabs(rv[0].cam.left.z) < 1e-12) rv[0].cam.left.z = 0.0;
    rv[1] = rv[0];
    rv[1].vp.divisor = rv[0].vp.divisor == 8 ? 4 : 8;
    flat_views += rv[0].cam.left.z == 0.0;
    const glm::dvec3 step{0.3 * (U(rng) - 0.5), 0.3 * (U(rng) - 0.5), 0.0};
    for (int f = 0; f < 8; ++f) {
      for (int b = 0; b < 2; ++b) {
        Camera cam = rv[b].cam;
        cam.pos_m += static_cast<double>(f) * (f < 4 ? step : 977.0 * step);  // steps, then long strides
        sc.render(cam, rv[b].vp, vb);
        spans_from_samples(vb, levels, rv[b].block_shift, ref);
        sb[b].block_shift = rv[b].block_shift;
        sc.render_spans(cam, rv[b].vp, sb[b]);
        CAPTURE(it);
        CAPTURE(f);
        CAPTURE(b);
        REQUIRE(sb[b].samples == vb.samples.size());
        REQUIRE(same_counters(sb[b].counters, vb.counters));
        REQUIRE(sb[b].spans.size() == ref.size());
        std::size_t differ = 0;
        for (std::size_t i = 0; i < ref.size(); ++i) differ += !same_span(sb[b].spans[i], ref[i]);
        REQUIRE(differ == 0);
        total_spans += ref.size();
      }
    }
  }
  CHECK(flat_views > static_cast<std::size_t>(runs) / 2);
  CHECK(total_spans > 20000u * static_cast<unsigned>(runs) / 120u);
}

TEST_CASE("spans_from_samples: definition on a hand-made buffer / keep_samples / bad arguments") {
  ViewBuffer vb;
  vb.width = 4;
  vb.height = 2;
  // Row 0: three samples at level 0 in block 0, then one in block 1 (block_shift 1: 2 texels).
  vb.samples = {{0, 0, 0.2f, 0}, {1, 0, 0.9f, 1}, {0, 1, 0.0f, 2}, {2, 0, 0.1f, 3},
                // Row 1: pixel 4 at level 1, pixel 6 (not adjacent) at level 1.
                {4, 4, 1.5f, 4}, {4, 5, 1.5f, 6}};
  std::vector<ViewSpan> s;
  spans_from_samples(vb, 10, 1, s);
  REQUIRE(s.size() == 4);
  CHECK(s[0].count == 3);
  CHECK(s[0].u_lo == 0);
  CHECK(s[0].u_hi == 1);
  CHECK(s[0].v_hi == 1);
  CHECK(s[1].first == 3);
  CHECK(s[2].level == 1);
  CHECK(s[3].pixel == 6);
  CHECK_THROWS_AS(spans_from_samples(vb, 10, 63, s), std::invalid_argument);
  CHECK_THROWS_AS(spans_from_samples(vb, 0, 7, s), std::invalid_argument);

  auto scene = plane_scene();
  const Camera cam = make_camera(pose_from_angles({4096.0, 4096.0, 1.7}, 30.0, -15.0), 1920, 1080);
  ViewParams vp;
  SpanBuffer a, b;
  b.keep_samples = true;
  scene->render_spans(cam, vp, a);
  scene->render_spans(cam, vp, b);
  CHECK_FALSE(a.has_samples);
  CHECK(b.has_samples);
  REQUIRE(a.spans.size() == b.spans.size());
  for (std::size_t i = 0; i < a.spans.size(); ++i) CHECK(same_span(a.spans[i], b.spans[i]));
  ViewBuffer vb2;
  scene->render(cam, vp, vb2);
  CHECK(finest_level(a, 21) == [&] {
    int f = 21;
    for (const ViewSample& x : vb2.samples) f = std::min(f, desired_level(x.lod, 21));
    return f;
  }());
  a.block_shift = 63;
  CHECK_THROWS_AS(scene->render_spans(cam, vp, a), std::invalid_argument);
}

TEST_CASE("aggregate_feedback over spans equals the per-sample aggregation (any tile size)") {
  std::mt19937_64 rng(77);
  auto scene = plane_scene();
  ViewBuffer vb;
  SpanBuffer sb;
  std::vector<TileUse> a, b;
  for (int it = 0; it < vtsim::test::property_runs(80); ++it) {
    const RandomView rv = random_view(rng, 4096.0, 4096.0);
    sb.block_shift = rv.block_shift;
    scene->render(rv.cam, rv.vp, vb);
    scene->render_spans(rv.cam, rv.vp, sb);
    for (const int tile : {128, 64, 256, 100, 1}) {  // 100: spans split by tiles, expanded
      for (const int levels : {21, 12}) {
        aggregate_feedback(vb, tile, levels, a);
        aggregate_feedback(sb, tile, levels, b);
        CAPTURE(it);
        CAPTURE(tile);
        REQUIRE(a.size() == b.size());
        std::size_t differ = 0;
        for (std::size_t i = 0; i < a.size(); ++i) differ += a[i].key != b[i].key || a[i].samples != b[i].samples;
        REQUIRE(differ == 0);
      }
    }
  }
  CHECK_THROWS_AS(aggregate_feedback(sb, 128, 22, b), std::invalid_argument);
}

TEST_CASE("clipmap span residency and span pop-in equal the per-sample forms on random states") {
  std::mt19937_64 rng(4242);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  auto scene = plane_scene();
  ViewBuffer vb;
  SpanBuffer sb;
  std::vector<std::int8_t> ref_before, ref_now;
  SpanLevels before, now;
  std::vector<Need> needs;
  std::size_t mixed = 0, spans = 0;
  for (int it = 0; it < 160; ++it) {
    RandomView rv = random_view(rng, 4096.0, 4096.0);
    if (it % 2 == 0) {  // walking cameras: the replay's case
      rv.cam = make_camera(pose_from_angles({4096.0 + 50.0 * U(rng), 4096.0 + 50.0 * U(rng), 1.0 + 3.0 * U(rng)},
                                            360.0 * U(rng), -5.0 - 40.0 * U(rng)),
                           1920, 1080);
      rv.vp = ViewParams{};
    }
    ClipmapParams p;
    p.tile_size = it % 3 == 0 ? 64 : 128;
    p.clipsize = p.tile_size * 8;
    p.filter_margin_texels = static_cast<int>(rng() % 3);
    p.invalid_border_tiles = static_cast<int>(rng() % 2);
    p.layers = 1 + static_cast<int>(rng() % 2);
    sb.block_shift = std::countr_zero(static_cast<unsigned>(p.tile_size));
    scene->render(rv.cam, rv.vp, vb);
    scene->render_spans(rv.cam, rv.vp, sb);
    Clipmap a(p);
    const int levels = a.num_levels();
    const std::int64_t gu = static_cast<std::int64_t>(std::floor(rv.cam.pos_m.x * 128.0));
    const std::int64_t gv = static_cast<std::int64_t>(std::floor(rv.cam.pos_m.y * 128.0));
    a.update_windows(gu, gv, static_cast<int>(rng() % 3));
    // Commit a random share of what the windows need (often none, some or all of a level).
    const double share = it % 4 == 0 ? 1.0 : U(rng);
    needs.clear();
    a.emit_needs(0, [](int, std::int64_t, std::int64_t) { return 0; }, needs);
    for (const Need& n : needs)
      if (U(rng) < share) a.commit(n.key);
    a.set_clamp(it % 5 == 0 ? static_cast<int>(rng() % 4) : 0);
    Clipmap b = a;  // the per-sample twin
    a.set_mark_sampled(false);
    b.set_mark_sampled(false);
    resident_levels(sb, a, before);
    ref_before.resize(vb.samples.size());
    b.resident_levels(vb.samples.data(), vb.samples.size(), ref_before.data());
    // More commits (visible pops), then the marked pass.
    for (const Need& n : needs)
      if (U(rng) < 0.5) {
        a.commit(n.key);
        b.commit(n.key);
      }
    a.set_mark_sampled(true);
    b.set_mark_sampled(true);
    resident_levels(sb, a, now);
    ref_now.resize(vb.samples.size());
    b.resident_levels(vb.samples.data(), vb.samples.size(), ref_now.data());
    CAPTURE(it);
    std::size_t bad = 0;
    for (std::size_t i = 0; i < sb.spans.size(); ++i) {
      const ViewSpan& s = sb.spans[i];
      for (std::uint32_t k = 0; k < s.count; ++k) {
        bad += (before.span[i] >= 0 ? before.span[i] : before.sample[before.offset[i] + k]) != ref_before[s.first + k];
        bad += (now.span[i] >= 0 ? now.span[i] : now.sample[now.offset[i] + k]) != ref_now[s.first + k];
      }
      mixed += now.span[i] < 0;
    }
    REQUIRE(bad == 0);
    spans += sb.spans.size();
    const PopinFrame ps = popin_stats(sb, now, &before, levels);
    const PopinFrame pr = popin_stats(vb, ref_now, &ref_before, levels);
    CHECK(ps.samples == pr.samples);
    CHECK(ps.blurry == pr.blurry);
    CHECK(ps.visible_pops == pr.visible_pops);
    CHECK(std::bit_cast<std::uint64_t>(ps.mean_deficit) == std::bit_cast<std::uint64_t>(pr.mean_deficit));
    CHECK(std::bit_cast<std::uint64_t>(ps.blurry_fraction) == std::bit_cast<std::uint64_t>(pr.blurry_fraction));
    const PopinFrame ps1 = popin_stats(sb, now, nullptr, levels);
    CHECK(ps1.blurry == popin_stats(vb, ref_now, nullptr, levels).blurry);
    // Marking what is sampled: the same slots.
    CHECK(a.resident_unsampled() == b.resident_unsampled());
  }
  // Most spans resolve whole; some go per sample (window edges, partly loaded levels).
  CHECK(mixed > 0);
  CHECK(mixed * 4 < spans);
}
