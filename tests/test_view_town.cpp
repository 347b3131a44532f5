#include <doctest/doctest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <glm/geometric.hpp>

#include "core/camera.h"
#include "core/error.h"
#include "core/view.h"
#include "core/view_spans.h"
#include "sim/view/mesh.h"
#include "sim/view/scene.h"
#include "sim/view/scene_mesh.h"
#include "sim/view/scene_town.h"

using namespace vtsim;

TEST_CASE("town: deterministic / every face owns a disjoint texel rectangle inside the texture") {
  SceneConfig cfg;
  cfg.kind = "town";
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
  cfg.kind = "town";
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
  CHECK_THROWS_WITH_AS(generate_town(bad_cfg), doctest::Contains("packs the town's faces into more than"), InputError);
}

namespace {

// Samples of two buffers of the same size that differ in any field (the LOD bit for bit).
std::size_t differing_samples(const ViewBuffer& a, const ViewBuffer& b) {
  std::size_t differ = 0;
  for (std::size_t i = 0; i < a.samples.size(); ++i)
    differ += a.samples[i].u != b.samples[i].u || a.samples[i].v != b.samples[i].v ||
              a.samples[i].pixel != b.samples[i].pixel ||
              std::bit_cast<std::uint32_t>(a.samples[i].lod) != std::bit_cast<std::uint32_t>(b.samples[i].lod);
  return differ;
}

double distance_to(const Mesh::Box& b, const glm::dvec3& p) {
  const glm::dvec3 d = glm::max(glm::max(b.lo - p, p - b.hi), glm::dvec3(0.0));
  return std::sqrt(glm::dot(d, d));
}

void check_same_counters(const ViewBuffer& a, const ViewBuffer& b) {
  CHECK(a.counters.sky == b.counters.sky);
  CHECK(a.counters.clipped == b.counters.clipped);
  CHECK(a.counters.backfacing == b.counters.backfacing);
  CHECK(a.counters.outside_texture == b.counters.outside_texture);
  CHECK(a.counters.untextured == b.counters.untextured);
}

}  // namespace

TEST_CASE("town: occlusion culling renders exactly what drawing every chunk in index order renders, from any warm start") {
  SceneConfig cfg;
  cfg.kind = "town";
  MeshScene culled(generate_town(cfg), scene_texture(cfg)), plain(generate_town(cfg), scene_texture(cfg));
  plain.set_occlusion_culling(false);
  const double S = town_size_m(cfg);
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  ViewBuffer a, b;
  std::size_t samples = 0;
  int skipping = 0;  // views rendered without back faces (the plain render draws them)
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
    skipping += culled.skips_back_faces(cam, vp);
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
    REQUIRE(differing_samples(a, b) == 0);
    check_same_counters(a, b);
    samples += a.samples.size();
  }
  CHECK(samples > 100000);
  CHECK(skipping > 20);
  CHECK(skipping < 60);
}

TEST_CASE("town: back faces are skipped only where the solids allow it, and the buffer is the same") {
  SceneConfig cfg;
  cfg.kind = "town";
  const Mesh mesh = generate_town(cfg);
  REQUIRE(mesh.solids.size() == 1u + 4u * 16u * 16u + 2u * 16u * 16u);  // below ground, buildings, walls
  MeshScene culled(mesh, scene_texture(cfg)), plain(mesh, scene_texture(cfg));
  plain.set_occlusion_culling(false);
  const double x0 = cfg.origin_x_m, y0 = cfg.origin_y_m;
  ViewParams vp;
  vp.divisor = 4;
  const auto at = [](glm::dvec3 p, double heading = 30.0, double pitch = -10.0) {
    return make_camera(pose_from_angles(p, heading, pitch), 640, 360);
  };
  // The street corner: clear.
  CHECK(culled.skips_back_faces(at({x0 + 8, y0 + 8, 1.7}), vp));
  CHECK_FALSE(plain.skips_back_faces(at({x0 + 8, y0 + 8, 1.7}), vp));
  // Inside the first building, and below the ground: not clear, and the back faces are seen.
  const Mesh::Box& house = mesh.solids[1];
  const glm::dvec3 inside = (house.lo + house.hi) * 0.5;
  ViewBuffer vb;
  for (const glm::dvec3& p : {inside, glm::dvec3(x0 + 8, y0 + 8, -1.0)}) {
    CAPTURE(p.z);
    CHECK_FALSE(culled.skips_back_faces(at(p), vp));
    culled.render(at(p, 45.0, 30.0), vp, vb);  // looking up: walls and ceiling, or the ground's underside
    CHECK(vb.counters.backfacing > 0);
  }
  // One metre off the building's −x wall: clear until the near plane's corners reach the nearest
  // solid. Their distance is near·sqrt(1 + (cx/f)² + (cy/f)²) for a centred principal point.
  const glm::dvec3 off(house.lo.x - 1.0, inside.y, 1.0);
  double nearest = INFINITY;
  for (const Mesh::Box& b : mesh.solids) nearest = std::min(nearest, distance_to(b, off));
  REQUIRE(nearest <= 1.0);
  const Camera cam = at(off, 180.0);
  const double ax = cam.cx / cam.focal_px, ay = cam.cy / cam.focal_px, k = std::sqrt(1.0 + ax * ax + ay * ay);
  vp.near_m = 0.999 * nearest / k;
  CHECK(culled.skips_back_faces(cam, vp));
  vp.near_m = 1.001 * nearest / k;
  CHECK_FALSE(culled.skips_back_faces(cam, vp));
  vp.near_m = 0.05;
  // A mesh without solids (an OBJ file) makes no promise.
  Mesh open = mesh;
  open.solids.clear();
  CHECK_FALSE(MeshScene(open, scene_texture(cfg)).skips_back_faces(at({x0 + 8, y0 + 8, 1.7}), vp));
  // Bad solids are rejected naming the box.
  Mesh bad = mesh;
  bad.solids[3].hi.y = std::nan("");
  CHECK_THROWS_WITH_AS(MeshScene(bad, scene_texture(cfg)), doctest::Contains("mesh solid 3"), InputError);
  bad.solids[3] = Mesh::Box{{1, 1, 1}, {0, 2, 2}};
  CHECK_THROWS_WITH_AS(MeshScene(bad, scene_texture(cfg)), doctest::Contains("lo > hi"), InputError);

  // Eye-level views along the building fronts (silhouettes everywhere), every divisor: the render
  // without back faces equals the one that draws them, sample for sample.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  int compared = 0;
  ViewBuffer a, b;
  for (int it = 0; it < 120; ++it) {
    const Mesh::Box& h = mesh.solids[1 + rng() % (mesh.solids.size() - 1)];
    const glm::dvec3 p(h.lo.x - 0.2 - 6.0 * U(rng), h.lo.y + (h.hi.y - h.lo.y) * U(rng), 0.3 + 3.0 * U(rng));
    const Camera c = make_camera(pose_from_angles(p, 360.0 * U(rng), -30.0 + 45.0 * U(rng)), 640, 360);
    ViewParams v;
    v.divisor = 1 << (rng() % 4);
    if (!culled.skips_back_faces(c, v)) continue;
    ++compared;
    culled.render(c, v, a);
    plain.render(c, v, b);
    CAPTURE(it);
    REQUIRE(a.samples.size() == b.samples.size());
    REQUIRE(differing_samples(a, b) == 0);
    check_same_counters(a, b);
  }
  CHECK(compared > 80);
}

TEST_CASE("town: render work counts add up, and culling is what removes the work") {
  SceneConfig cfg;
  cfg.kind = "town";
  const Mesh mesh = generate_town(cfg);
  MeshScene culled(mesh, scene_texture(cfg)), plain(mesh, scene_texture(cfg));
  plain.set_occlusion_culling(false);
  const Camera cam = make_camera(pose_from_angles({cfg.origin_x_m + 30.0, cfg.origin_y_m + 8.0, 1.7}, 90.0, -5.0), 1920, 1080);
  ViewParams vp;
  vp.divisor = 8;
  SpanBuffer sb;
  sb.block_shift = 7;
  const auto counts = [&](const MeshScene& m) {
    m.render_spans(cam, vp, sb);
    const MeshScene::RenderStats w = MeshScene::last_render_stats();
    CHECK(w.chunks * 16 >= mesh.tris.size());  // at most 16 triangles a chunk
    CHECK(w.chunks <= mesh.tris.size());
    CHECK(w.chunks_occluded <= w.chunks_in_frustum);
    CHECK(w.chunks_in_frustum <= w.chunks);
    CHECK(w.back_faces_skipped + w.triangles_occluded + w.triangles_rasterised <= w.triangles_visited);
    CHECK(w.raster_rows >= w.triangles_rasterised);  // a rasterised triangle spans a row at least
    CHECK(w.resolve_samples >= sb.samples);          // runs also hold clipped and outside samples
    CHECK(w.resolve_runs <= sb.spans.size() + w.resolve_samples);
    CHECK(w.visible_triangles > 0);
    return w;
  };
  const MeshScene::RenderStats a = counts(culled), b = counts(plain);
  // The same buffer either way; without culling nothing is culled and every triangle of the
  // frustum's chunks is visited and drawn.
  CHECK(a.resolve_samples == b.resolve_samples);
  CHECK(a.resolve_runs == b.resolve_runs);
  CHECK(a.visible_triangles <= b.visible_triangles);  // the plain render also keeps back faces
  CHECK(b.chunks_occluded == 0);
  CHECK(b.back_faces_skipped == 0);
  CHECK(b.triangles_occluded == 0);
  CHECK(a.chunks_occluded > 0);
  CHECK(a.back_faces_skipped > 0);
  CHECK(a.triangles_visited * 4 < b.triangles_visited);
  CHECK(a.depth_tests * 2 < b.depth_tests);
  // Counted again from scratch on every render: the same camera gives the same counts.
  const MeshScene::RenderStats a2 = counts(culled);
  CHECK(a2.triangles_visited <= a.triangles_visited);  // the warm start may only cull more
  CHECK(a2.resolve_samples == a.resolve_samples);
}

namespace {

// The town of `cfg` repeated tiles × tiles side by side (tile_town: an instanced town).
Mesh town_tiled_for_test(const SceneConfig& cfg, int tiles) {
  return tile_town(generate_town(cfg), town_size_m(cfg), tiles);
}

}  // namespace

TEST_CASE("town: the BVH walk renders an instanced town exactly as drawing every chunk does, visiting a fraction of it") {
  SceneConfig cfg;
  cfg.kind = "town";
  cfg.town_blocks = 6;
  const int tiles = 4;
  const Mesh mesh = town_tiled_for_test(cfg, tiles);
  const double S = town_size_m(cfg) * tiles;
  cfg.size_x_m = cfg.size_y_m = S;
  cfg.texels_per_m = 4.0;
  MeshScene culled(mesh, scene_texture(cfg)), plain(mesh, scene_texture(cfg));
  plain.set_occlusion_culling(false);
  std::mt19937_64 rng(2028);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  ViewBuffer a, b;
  SpanBuffer sa, sb;
  sa.block_shift = sb.block_shift = 7;
  std::size_t samples = 0;
  int skipping = 0;
  for (int it = 0; it < 40; ++it) {
    const double z = it % 5 == 4 ? 20.0 + 200.0 * U(rng) : 0.3 + 2.5 * U(rng);
    const Camera cam = make_camera(pose_from_angles({S * U(rng), S * U(rng), z}, 360.0 * U(rng), -50.0 + 60.0 * U(rng)), 640, 360);
    ViewParams vp;
    const int divisors[] = {1, 2, 4, 8, 16};
    vp.divisor = divisors[rng() % 5];
    CAPTURE(it);
    // skips_back_faces walks the solids' BVH: the same answer as testing every solid.
    const double ax = std::max(cam.cx, cam.width - cam.cx) / cam.focal_px;
    const double ay = std::max(cam.cy, cam.height - cam.cy) / cam.focal_px;
    const double reach = vp.near_m * std::sqrt(1.0 + ax * ax + ay * ay) * (1.0 + 0x1p-20);
    bool clear = true;
    for (const Mesh::Box& box : mesh.solids) clear = clear && distance_to(box, cam.pos_m) > reach;
    CHECK(culled.skips_back_faces(cam, vp) == clear);
    skipping += clear;
    culled.render(cam, vp, a);
    plain.render(cam, vp, b);
    REQUIRE(a.samples.size() == b.samples.size());
    REQUIRE(differing_samples(a, b) == 0);
    check_same_counters(a, b);
    // The span renderer walks the same hierarchy: the same spans with and without culling.
    culled.render_spans(cam, vp, sa);
    plain.render_spans(cam, vp, sb);
    REQUIRE(sa.spans.size() == sb.spans.size());
    for (std::size_t i = 0; i < sa.spans.size(); ++i) {
      const ViewSpan& x = sa.spans[i];
      const ViewSpan& y = sb.spans[i];
      REQUIRE((x.u_lo == y.u_lo && x.u_hi == y.u_hi && x.v_lo == y.v_lo && x.v_hi == y.v_hi && x.pixel == y.pixel &&
               x.count == y.count && x.first == y.first && x.level == y.level));
    }
    samples += a.samples.size();
  }
  CHECK(samples > 50000);
  CHECK(skipping > 10);
  CHECK(skipping < 40);
  // Down the first street at eye height: the walk reaches a small part of the chunks, and its
  // nodes are of the order of what it draws (not of the mesh).
  const Camera street = make_camera(pose_from_angles({30.0, 8.0, 1.7}, 0.0, -5.0), 1280, 720);
  ViewParams vp;
  vp.divisor = 8;
  culled.render(street, vp, a);
  culled.render(street, vp, a);
  const MeshScene::RenderStats w = MeshScene::last_render_stats();
  plain.render(street, vp, b);
  const MeshScene::RenderStats all = MeshScene::last_render_stats();
  CHECK(w.chunks * 16 >= mesh.tris.size());
  CHECK(w.chunks <= mesh.tris.size());
  CHECK(w.nodes_visited > 0);
  CHECK(w.chunks_in_frustum * 4 < all.chunks_in_frustum);
  CHECK(w.nodes_visited * 4 < 2 * w.chunks);
  // 24-byte triangles and their 4-byte mesh indices over shared corners and texture
  // coordinates, 32-byte BVH nodes: the town's layout stays under 100 bytes a triangle (95
  // untiled; docs/view.md).
  CHECK(culled.memory_bytes() <= 100 * culled.triangle_count());
  MESSAGE("chunks ", w.chunks, " reached ", w.chunks_in_frustum, " of ", all.chunks_in_frustum, " in the frustum; nodes ", w.nodes_visited);
}
