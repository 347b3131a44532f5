// Mesh renderer scaling (issue 28 §3): the feedback render at divisor 8 of the same street views
// in towns of ~10^3 to ~10^7 triangles — the town generated over more blocks, and for the largest
// size that town tiled 2 × 2 (instanced: the same blocks side by side) — so the total grows a
// thousandfold while what the camera sees stays a street's worth. Per size: ms per frame against
// the ~10^4-triangle town rendered side by side in the same run (harness ratio = ref / ours, so
// 0.5 is "twice the time"), triangles total and visible, chunks and BVH nodes touched, and the
// scene's memory per triangle (MeshScene::memory_bytes, exact from capacities).
// Usage: bench_mesh_scaling [--frames N] [--max-tris N] [common harness flags: --quick --reps N
// --json FILE --filter S]. Quick: sizes up to ~10^5, 6 frames.
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/view.h"
#include "core/view_spans.h"
#include "sim/view/mesh.h"
#include "sim/view/scene.h"
#include "sim/view/scene_mesh.h"
#include "sim/view/scene_town.h"
#include "harness.h"

using namespace vtsim;

namespace {

struct ScaleSize {
  const char* name;
  int blocks;  // town_blocks of the generated town
  int tiles;   // that town repeated tiles × tiles
};
// Triangles ≈ blocks² · 60 + (blocks + 1)² · 2 per tile (4 buildings and 2 walls of 10 triangles a
// block; two per ground cell).
constexpr ScaleSize kSizes[] = {{"1e3", 4, 1}, {"1e4", 13, 1}, {"1e5", 40, 1}, {"1e6", 128, 1}, {"1e7", 204, 2}};
constexpr const char* kRefSize = "1e4";

// The generated town of `blocks` blocks, tiled: tile (i, j) shifted by (i, j)·S. Texture
// coordinates repeat (the renderer's cost does not depend on them); the half-space under the
// ground is kept once.
Mesh scaling_town(int blocks, int tiles, SceneConfig& cfg) {
  cfg.kind = "town";
  cfg.town_blocks = blocks;
  cfg.texels_per_m = 4.0;  // small: the faces of 204² blocks fit into a 2^34-texel texture
  const double S = town_size_m(cfg);
  cfg.size_x_m = cfg.size_y_m = std::max(4.0 * S, 2048.0);  // the ground, then the shelf-packed walls and roofs
  const Mesh base = generate_town(cfg);
  return tiles == 1 ? base : tile_town(base, S, tiles);
}

struct Built {
  std::string name;
  std::unique_ptr<MeshScene> scene;
};

}  // namespace

int main(int argc, char** argv) {
  int frames = 0;
  double max_tris = 2e7;
  std::vector<char*> hargv{argv[0]};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if ((a == "--frames" || a == "--max-tris") && i + 1 < argc) {
      char* end = nullptr;
      const double v = std::strtod(argv[++i], &end);
      if (end == argv[i] || *end != '\0' || !(v >= 2.0 && v <= 1e9)) {
        fmt::print(stderr, "bench_mesh_scaling: {} must be a number in [2, 1e9]\n", a);
        return 2;
      }
      (a == "--frames" ? frames = static_cast<int>(v) : 0);
      if (a == "--max-tris") max_tris = v;
    } else {
      hargv.push_back(argv[i]);
    }
  }
  bench::Harness h("mesh_scaling", static_cast<int>(hargv.size()), hargv.data(), 5, 3,
                   "  --frames N      consecutive 60 Hz frames per repetition (default 20; quick 6)\n"
                   "  --max-tris N    skip sizes above N triangles (default 2e7; quick 2e5)\n");
  if (frames == 0) frames = h.pick(20, 6);
  if (h.quick()) max_tris = std::min(max_tris, 2e5);
  // Two street-level walks (1.5 m/s at 1.7 m, the head turning ±5°), the same at every size:
  // "block", from the first street into the corner block at 45°, where the same buildings hide
  // all that lies beyond them (the visible set stays put: the target); "street", down the
  // second street, whose canyon runs to the town's far side (what lies along it near the vanishing
  // point grows with the town, most of it thinner than the samples).
  struct View {
    const char* name;
    glm::dvec3 at;
    double yaw_deg;
  };
  const View views[] = {{"block", {30.0, 8.0, 1.7}, 45.0}, {"street", {30.0, 84.0, 1.7}, 0.0}};
  ViewParams vp;
  vp.divisor = 8;
  SpanBuffer sb;
  std::vector<Built> built;
  for (const ScaleSize& sz : kSizes) {
    const double est = (sz.blocks * sz.blocks * 60.0 + (sz.blocks + 1.0) * (sz.blocks + 1.0) * 2.0) * sz.tiles * sz.tiles;
    if (est > max_tris * 1.2 && std::string(sz.name) != kRefSize) continue;
    SceneConfig cfg;
    const Mesh m = scaling_town(sz.blocks, sz.tiles, cfg);
    built.push_back(Built{sz.name, std::make_unique<MeshScene>(m, scene_texture(cfg))});
  }
  const MeshScene* ref = nullptr;
  for (const Built& b : built)
    if (b.name == kRefSize) ref = b.scene.get();
  // One repetition: frames 1 .. N−1 in order (the warm start of each frame is the previous one's,
  // as in a replay); the setup renders frame 0, so the scene's scratch is sized outside the timing.
  std::vector<Camera> cams;
  const auto side = [&](const std::string& name, const MeshScene* s) {
    return bench::Side{name, [&, s] { s->render_spans(cams[0], vp, sb); },
                       [&, s] {
                         for (int f = 1; f < frames; ++f) s->render_spans(cams[static_cast<std::size_t>(f)], vp, sb);
                         bench::do_not_optimize(sb.samples);
                       }};
  };
  nlohmann::json report = nlohmann::json::array();
  for (const View& view : views) {
  cams.clear();
  const double c = std::cos(view.yaw_deg * M_PI / 180.0), sn = std::sin(view.yaw_deg * M_PI / 180.0);
  for (int f = 0; f < frames; ++f) {
    const double t = f / 60.0;
    cams.push_back(make_camera(pose_from_angles(view.at + glm::dvec3(c, sn, 0.0) * (1.5 * t),
                                                view.yaw_deg + 5.0 * std::sin(2 * M_PI * 0.3 * t), -5.0),
                               1280, 720));
  }
  fmt::print("view \"{}\"\n", view.name);
  fmt::print("{:>5} {:>10} {:>8} {:>9} {:>8} {:>8} {:>9} {:>8}  (divisor 8, {} frames; ratio = ref / ours)\n", "size",
             "triangles", "visible", "in frust", "drawn", "occluded", "nodes", "B/tri", frames);
  for (const Built& b : built) {
    // Stats of the walk's frames, one pass (medians over frames).
    std::vector<double> vis, infr, drawn, occl, nodes;
    std::uint64_t sum = 0xcbf29ce484222325ULL;  // FNV-1a of the spans: the output, to compare builds by
    const auto mix = [&](std::uint64_t x) {
      for (int i = 0; i < 8; ++i) sum = (sum ^ ((x >> (8 * i)) & 0xff)) * 0x100000001b3ULL;
    };
    for (const Camera& cam : cams) {
      b.scene->render_spans(cam, vp, sb);
      for (const ViewSpan& sp : sb.spans) {
        mix(static_cast<std::uint64_t>(sp.u_lo) ^ (static_cast<std::uint64_t>(sp.v_hi) << 32));
        mix(static_cast<std::uint64_t>(sp.u_hi) ^ (static_cast<std::uint64_t>(sp.v_lo) << 32));
        mix(sp.pixel ^ (static_cast<std::uint64_t>(sp.count) << 32));
        mix(sp.first ^ (static_cast<std::uint64_t>(static_cast<std::uint32_t>(sp.level)) << 32));
      }
      const MeshScene::RenderStats st = MeshScene::last_render_stats();
      vis.push_back(st.visible_triangles);
      infr.push_back(st.chunks_in_frustum);
      drawn.push_back(st.chunks_in_frustum - st.chunks_occluded);
      occl.push_back(st.chunks_occluded);
      nodes.push_back(st.nodes_visited);
    }
    const auto med = [](std::vector<double> v) {
      std::sort(v.begin(), v.end());
      return v[v.size() / 2];
    };
    const double tris = static_cast<double>(b.scene->triangle_count());
    const double bpt = static_cast<double>(b.scene->memory_bytes()) / tris;
    fmt::print("{:>5} {:>10} {:>8} {:>9} {:>8} {:>8} {:>9} {:>8.1f}  spans {:016x}\n", b.name, b.scene->triangle_count(),
               med(vis), med(infr), med(drawn), med(occl), med(nodes), bpt, sum);
    bench::Case cs{.name = fmt::format("render_div8_{}_{}", view.name, b.name), .metric = bench::Metric::kNsPerOp,
                   .work = frames - 1.0};
    cs.params = {{"view", view.name}, {"triangles", b.scene->triangle_count()}, {"visible_triangles", med(vis)},
                {"chunks_in_frustum", med(infr)}, {"chunks_drawn", med(drawn)}, {"nodes_visited", med(nodes)},
                {"bytes_per_triangle", bpt}, {"spans_fnv1a", fmt::format("{:016x}", sum)}};
    // Issue 28: within 2× the 10^4 scene's time where the visible set stays put.
    if (b.name == "1e7" && std::string(view.name) == "block") cs.target_ratio = 0.5;
    const bench::Result* r = h.compare(cs, side(b.name, b.scene.get()), side(kRefSize, ref));
    if (r) report.push_back({{"size", b.name}, {"ms_per_frame", r->ours.median * 1e-6}, {"ref_ms_per_frame", r->ref.median * 1e-6},
                             {"ratio", r->ratio}, {"params", cs.params}});
  }
  }
  h.param("curve", report);
  h.param("frames", frames);
  return h.finish();
}
