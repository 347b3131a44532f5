// `vtsim gl calibrate-upload` on this GL (llvmpipe in CI; docs/gpu.md, "Calibrating the GPU
// upload"): the GL client's own copy (StreamedVt) timed at batches of pages and page sizes, both
// fits finite and non-negative, the profile written as the command writes it loads as a config
// with positive finite [upload] keys, and no GL error.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

#include "core/error.h"
#include "gl/gl_calibrate.h"
#include "gl/gl_renderer.h"
#include "gl_test_util.h"
#include "sim/run/replay_config.h"
#include "sim/view/scene.h"

using namespace vtsim;

TEST_CASE("gl: calibrate-upload times the client's page copy and writes a profile that loads") {
  gl_test::Shared& gs = gl_test::shared();
  gs.warnings.clear();
  const int errors_before = gs.ctx.errors();
  SceneConfig sc;
  sc.kind = "plane";
  sc.texels_per_m = 32;
  sc.size_x_m = sc.size_y_m = 16.0;  // 512² texels
  gl::Renderer r(gs.ctx, sc);
  gl::UploadCalibrateOptions o;
  o.tile = 64;
  o.border = 4;
  o.channels = 4;
  o.batches = {1, 4, 16};
  o.reps = 3;
  const gl::UploadCalibration c = gl::calibrate_upload(r, o);
  CHECK(gs.warnings.empty());
  CHECK(gs.ctx.errors() == errors_before);
  REQUIRE(c.points.size() == 9);  // 3 sizes × 3 batches
  CHECK(c.points[0].bytes == 40u * 40u * 4u);
  CHECK(c.points[3].bytes == 72u * 72u * 4u);
  CHECK(c.points[8].bytes == 136u * 136u * 4u);
  for (const gl::UploadPoint& p : c.points) {
    CAPTURE(p.bytes);
    CAPTURE(p.batch);
    CHECK(p.complete_us > 0.0);
    CHECK(p.complete_us >= p.submit_us);
    CHECK(std::isfinite(p.gpu_us));
    CHECK(p.gpu_us >= 0.0);
  }
  for (const UploadFit* f : {&c.gpu, &c.cpu}) {
    CHECK(std::isfinite(f->per_tile_us));
    CHECK(f->per_tile_us >= 0.0);
    CHECK(std::isfinite(f->MBps));
    CHECK(f->MBps >= 0.0);
  }
  // The profile as the command writes it (the CPU clock: on llvmpipe the copy is CPU work, so its
  // wall time grows with the bytes and the pages); it loads with the [upload] keys it fitted.
  const std::string toml = upload_profile_toml(c.cpu, c.cpu_samples, "test");
  const std::string path = (std::filesystem::temp_directory_path() / ("vtsim-gl-upload-" + std::to_string(::getpid()) + ".toml")).string();
  {
    std::ofstream f(path);
    f << toml;
  }
  const ReplayConfig cfg = load_replay_config(path, {});
  std::filesystem::remove(path);
  CHECK(std::isfinite(cfg.upload.per_tile_us));
  CHECK(std::isfinite(cfg.upload.link_MBps));
  CHECK(cfg.upload.per_tile_us + cfg.upload.link_MBps > 0.0);
  CHECK(cfg.upload.link_MBps > 0.0);
  CHECK(std::abs(cfg.upload.per_tile_us - c.cpu.per_tile_us) <= 1e-4);  // written with 4 decimals
  CHECK_THROWS_AS(gl::calibrate_upload(r, [] {
                    gl::UploadCalibrateOptions bad;
                    bad.batches = {0};
                    return bad;
                  }()),
                  InputError);
}
