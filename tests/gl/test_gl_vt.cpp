// Image correctness of the GL client's virtual texture (docs/gpu.md): fully resident, it renders
// the image of a plain mipmapped texture within 1/255 on >= 99.5 % of pixels; with level 0
// missing, its level-0 pages show their level-1 ancestors' texels (the plain texture's level 1),
// never garbage.
#include <doctest/doctest.h>

#include <algorithm>
#include <cstdlib>
#include <vector>

#include "core/camera.h"
#include "gl/gl_context.h"
#include "gl/gl_renderer.h"
#include "gl_test_util.h"
#include "sim/view/scene.h"

namespace {

using namespace vtsim;


// Fraction of pixels whose channels all differ by at most `tol`, and how many differ at all.
double within(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b, int tol, std::size_t& differing) {
  std::size_t ok = 0, n = a.size() / 4;
  differing = 0;
  for (std::size_t i = 0; i < n; ++i) {
    int worst = 0;
    for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(int{a[4 * i + static_cast<std::size_t>(c)]} - int{b[4 * i + static_cast<std::size_t>(c)]}));
    ok += worst <= tol;
    differing += worst > 0;
  }
  return static_cast<double>(ok) / static_cast<double>(n);
}

}  // namespace

TEST_CASE("gl: a fully resident virtual texture renders the plain mipmapped texture; a missing level falls back") {
  SceneConfig cfg;
  cfg.kind = "plane";
  cfg.size_x_m = cfg.size_y_m = 8.0;  // a 1024² texture at 128 texels/m: 11 levels, 347 pages
  cfg.texels_per_m = 128.0;
  gl_test::Shared& gs = gl_test::shared();
  gs.warnings.clear();
  gl::Renderer r(gs.ctx, cfg);
  // Looking along the plane: levels 0 to 4 on screen.
  const Camera cam = make_camera(pose_from_angles({4.0, -0.5, 0.6}, 90.0, -20.0), 640, 360);
  gl::FeedbackSettings fs;
  int w = 0, h = 0;
  r.draw_textured(cam, fs, false, 0, -1);
  const std::vector<std::uint8_t> plain = r.read_main(w, h);
  r.draw_textured(cam, fs, true, 0, -1);
  const std::vector<std::uint8_t> vt = r.read_main(w, h);
  std::size_t differing = 0;
  const double resident = within(plain, vt, 1, differing);
  INFO("resident: ", 100.0 * resident, " % within 1/255, ", differing, " pixels differ at all");
  CHECK(resident >= 0.995);

  r.draw_textured(cam, fs, true, 0, 0);
  const std::vector<std::uint8_t> vt_missing = r.read_main(w, h);
  r.draw_textured(cam, fs, false, 1, -1);
  const std::vector<std::uint8_t> plain_level1 = r.read_main(w, h);
  const double fallback = within(plain_level1, vt_missing, 1, differing);
  std::size_t changed = 0;
  within(plain, vt_missing, 1, changed);
  INFO("level 0 missing: ", 100.0 * fallback, " % within 1/255 of the plain texture at level >= 1; ", changed,
       " pixels changed from the resident image");
  CHECK(fallback >= 0.995);
  CHECK(changed > static_cast<std::size_t>(w) * static_cast<std::size_t>(h) / 20);  // level 0 was on screen
  CHECK(gs.warnings.empty());
}
