// Wavefront OBJ meshes (scene.kind = mesh): parsed with the loader's limits, built into a
// MeshScene (which refuses degenerate or non-finite triangles), then rendered from three cameras
// placed from the mesh's bounds. Each frame must keep the span renderer's contract (docs/view.md,
// "Spans"): render_spans gives exactly spans_from_samples of render()'s buffer, and expanding the
// spans gives exactly render()'s samples.
#include <glm/geometric.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>

#include "fuzz_targets.h"
#include "core/camera.h"
#include "sim/view/mesh.h"
#include "sim/view/scene_mesh.h"
#include "sim/trace/trace_transform.h"
#include "core/view_spans.h"
#include "view_test_util.h"

namespace vtsim::fuzz {

namespace {

[[noreturn]] void fail(const std::string& what) {
  std::fprintf(stderr, "vtsim fuzz obj: %s\n", what.c_str());
  std::abort();
}

using test::same_counters;
using test::same_sample;
using test::same_span;

void check_frame(const MeshScene& scene, const Camera& cam, const ViewParams& p, const std::string& which) {
  ViewBuffer vb;
  scene.render(cam, p, vb);
  SpanBuffer sb;
  sb.block_shift = 7;
  scene.render_spans(cam, p, sb);
  std::vector<ViewSpan> ref;
  spans_from_samples(vb, mip_level_count(scene.texture()), sb.block_shift, ref);
  if (sb.spans.size() != ref.size()) fail(which + ": span count differs from the per-sample reference");
  for (std::size_t i = 0; i < ref.size(); ++i)
    if (!same_span(sb.spans[i], ref[i])) fail(which + ": span " + std::to_string(i) + " differs from the reference");
  if (!same_counters(sb.counters, vb.counters)) fail(which + ": counters differ from render()'s");
  if (sb.samples != vb.samples.size()) fail(which + ": sample count differs from render()'s");
  std::vector<ViewSample> expanded;
  expand_spans(sb, 0, sb.spans.size(), expanded);
  if (expanded.size() != vb.samples.size()) fail(which + ": expanded spans differ in size from render()'s samples");
  for (std::size_t i = 0; i < expanded.size(); ++i)
    if (!same_sample(expanded[i], vb.samples[i])) fail(which + ": expanded sample " + std::to_string(i) + " differs");
}

}  // namespace

void obj(const std::uint8_t* data, std::size_t size) {
  Mesh mesh;
  std::optional<MeshScene> scene;
  expect_accept_or_reject("obj", [&] {
    const std::string text(reinterpret_cast<const char*>(data), size);
    ObjLimits limits;
    limits.max_triangles = 4096;  // keeps a run fast; the limit itself is tested (InputError)
    limits.max_vertices = 16384;
    mesh = parse_obj(text, "fuzz.obj", nullptr, limits);
    scene.emplace(mesh, TextureExtent{1 << 20, 1 << 20});
  });
  if (!scene) return;
  must_succeed("obj", "rendering an accepted mesh", [&] {
    glm::dvec3 lo = mesh.positions.empty() ? glm::dvec3(0.0) : mesh.positions[0], hi = lo;
    for (const auto& q : mesh.positions) {
      lo = glm::min(lo, q);
      hi = glm::max(hi, q);
    }
    const glm::dvec3 c = lo * 0.5 + hi * 0.5;
    const double reach = std::max(1.0, glm::length(hi * 0.5 - lo * 0.5) * 3.0);
    struct View {
      glm::dvec3 pos;
      double yaw, pitch;
      const char* name;
    };
    const View views[] = {{c - glm::dvec3(reach, 0.0, 0.0), 0.0, 0.0, "from -x"},
                          {c + glm::dvec3(0.3 * reach, 0.2 * reach, 0.5 * reach), 200.0, -50.0, "from above"},
                          {c, 45.0, 10.0, "at the centre"}};
    for (const View& v : views) {
      if (!std::isfinite(v.pos.x) || !std::isfinite(v.pos.y) || !std::isfinite(v.pos.z)) continue;
      Pose pose;
      pose.pos_m = v.pos;
      pose.q = yaw_pitch_quat(v.yaw, v.pitch);
      const Camera cam = make_camera(pose, 64, 36);
      for (const bool aniso : {false, true}) {
        ViewParams p;
        p.divisor = 1;
        p.anisotropic = aniso;
        check_frame(*scene, cam, p, std::string(v.name) + (aniso ? " (anisotropic)" : ""));
      }
    }
  });
}

}  // namespace vtsim::fuzz
