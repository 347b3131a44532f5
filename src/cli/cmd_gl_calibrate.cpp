// vtsim gl calibrate-upload: time the GL client's page copy on this machine's GL and write the
// simulated clock's upload profile (docs/gpu.md, "Calibrating the GPU upload"). A `gl`
// subcommand, not a `calibrate` flag: it needs the GL context (exit 2 without EGL, as every gl
// command) and vtsim_gl, which `vtsim calibrate` and vtsim_lib stay free of; its [upload] keys do
// not overlap calibrate's [disk], [decode] and [io], so the two profiles merge as `-c io.toml -c
// upload.toml`.
#include <fmt/format.h>

#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "cli/cli_io.h"
#include "cli/commands.h"
#include "core/error.h"
#ifdef VTSIM_HAVE_GL
#include "gl/gl_calibrate.h"
#include "gl/gl_context.h"
#include "gl/gl_renderer.h"
#include "sim/run/real_replay.h"
#include "sim/run/replay.h"
#include "sim/run/replay_config.h"
#include "stream/store/tile_store.h"
#endif

namespace vtsim::cli {

namespace gl_cal_cmd {

struct UploadArgs {
  std::string store, out;
  std::string batches = "1,4,16,64";
  std::string tiles;  // payload sides; default: the store's, half and twice
  std::string clock = "auto";
  int reps = 7;
  std::uint64_t seed = 1;
  bool json = false, quiet = false;
};

std::vector<int> int_list(const std::string& flag, const std::string& s) {
  std::vector<int> v;
  std::stringstream in(s);
  std::string part;
  while (std::getline(in, part, ',')) {
    std::size_t used = 0;
    int x = 0;
    try {
      x = std::stoi(part, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != part.size()) throw InputError(flag, fmt::format("'{}' is not a comma-separated list of integers", s));
    v.push_back(x);
  }
  if (v.empty()) throw InputError(flag, "empty list");
  return v;
}

#ifdef VTSIM_HAVE_GL

void run_upload(const UploadArgs& a) {
  if (a.store.empty()) throw InputError("--store", "required (the tile store whose pages are timed)");
  if (a.clock != "auto" && a.clock != "gpu" && a.clock != "cpu")
    throw InputError("--clock", fmt::format("expected auto, gpu or cpu, got '{}'", a.clock));
  check_output("--output", a.out);
  if (a.json && a.out == "-") throw InputError("--output", "--json already prints to stdout: give a file or drop --json");
  gl::UploadCalibrateOptions o;
  o.batches = int_list("--batches", a.batches);
  if (!a.tiles.empty()) o.tiles = int_list("--tiles", a.tiles);
  o.reps = a.reps;
  o.seed = a.seed;
  const TileStore store = TileStore::open(a.store);
  for (const std::string& w : store.header().warnings) warn(w);
  ReplayConfig cfg;
  cfg.run.system = "vt";
  for (const std::string& w : bind_store_texture(cfg, store)) warn(w);
  o.tile = cfg.texture.tile_size;
  o.border = cfg.texture.border;
  o.channels = static_cast<int>(store.layer(0).channels);
  if (store.layer(0).bits != 8)
    throw InputError("--store", fmt::format("layer 0 has {}-bit channels; the GL client copies 8-bit ones", store.layer(0).bits));
  gl::Context ctx(warn);
  SceneConfig sc = scene_config_of(cfg);
  sc.kind = "plane";  // nothing is drawn: the scene only sizes the page table
  gl::Renderer r(ctx, sc);
  gl::UploadProgress progress;
  if (!a.quiet) progress = [](const std::string& s) { fmt::print(stderr, "vtsim: timing {}\n", s); };
  const gl::UploadCalibration c = gl::calibrate_upload(r, o, progress);
  // auto: the GPU's timer when it saw the copies (UploadCalibration::gpu_saw_copies), else the CPU's.
  const bool gpu_saw = c.gpu_saw_copies;
  const bool gpu = a.clock == "gpu" || (a.clock == "auto" && gpu_saw);
  const std::string clock_used = gpu ? "gpu" : "cpu";
  if (a.clock == "gpu" && !gpu_saw)
    warn("the GL_TIME_ELAPSED queries measured under a tenth of the submitting thread's wall time on the largest frame: this GL "
         "copies on the CPU (--clock cpu fits that)");
  const std::string source = fmt::format("{} ({}, {}), {} clock ({}){}, {} repetitions, medians", ctx.renderer(), ctx.version(), ctx.platform(),
                                         clock_used, gpu ? "GL_TIME_ELAPSED of the frame's copies" : "wall time to glFinish",
                                         a.clock == "auto" ? " chosen by --clock auto" : "", a.reps);
  const std::string toml = upload_profile_toml(gpu ? c.gpu : c.cpu, gpu ? c.gpu_samples : c.cpu_samples, source);
  if (!a.out.empty()) write_output(a.out, toml);
  if (a.json) {
    nlohmann::json j;
    j["renderer"] = ctx.renderer();
    j["gl_version"] = ctx.version();
    j["gl_errors"] = ctx.errors();
    for (const gl::UploadPoint& p : c.points)
      j["points"].push_back({{"tile", p.tile}, {"border", p.border}, {"channels", p.channels}, {"page_bytes", p.bytes},
                             {"pages_per_frame", p.batch}, {"reps", p.reps}, {"gpu_us", p.gpu_us}, {"submit_us", p.submit_us},
                             {"complete_us", p.complete_us}});
    const auto fit = [](const UploadFit& f) {
      return nlohmann::json{{"per_tile_us", f.per_tile_us}, {"link_MBps", f.MBps}, {"per_frame_us", f.per_frame_us}, {"model_us", f.model_us},
                            {"rel_residual", f.rel_residual}, {"max_abs_rel_residual", f.max_abs_rel}, {"notes", f.notes}};
    };
    j["fit"] = {{"gpu", fit(c.gpu)}, {"cpu", fit(c.cpu)}};
    j["profile"] = {{"upload.per_tile_us", (gpu ? c.gpu : c.cpu).per_tile_us}, {"upload.link_MBps", (gpu ? c.gpu : c.cpu).MBps}};
    j["clock"] = clock_used;
    fmt::print("{}\n", j.dump(2));
    return;
  }
  if (a.out.empty()) {
    fmt::print("{}", toml);
    return;
  }
  if (a.out == "-" || a.quiet) return;
  fmt::print("{:>10} {:>6} {:>12} {:>12} {:>12}\n", "page B", "pages", "GPU us", "submit us", "finish us");
  for (const gl::UploadPoint& p : c.points)
    fmt::print("{:>10} {:>6} {:>12.1f} {:>12.1f} {:>12.1f}\n", p.bytes, p.batch, p.gpu_us, p.submit_us, p.complete_us);
  fmt::print("GPU clock: per_tile_us {:.2f}, link_MBps {:.1f} (largest residual {:.1f} %); CPU clock: per_tile_us {:.2f}, link_MBps {:.1f} "
             "({:.1f} %)\n",
             c.gpu.per_tile_us, c.gpu.MBps, c.gpu.max_abs_rel * 100, c.cpu.per_tile_us, c.cpu.MBps, c.cpu.max_abs_rel * 100);
  fmt::print("wrote {} ({} clock)\n", a.out, clock_used);
}

#else

void run_upload(const UploadArgs&) {
  throw InputError("gl", "this vtsim was built without libepoxy (Debian: libepoxy-dev libegl-dev); rebuild with it");
}

#endif

}  // namespace gl_cal_cmd

void register_gl_calibrate_command(CLI::App& gl) {
  auto a = std::make_shared<gl_cal_cmd::UploadArgs>();
  auto* c = gl.add_subcommand("calibrate-upload",
                              "Time the GL client's page copy (PBO ring + glTextureSubImage2D, GL timer queries) and write the simulated "
                              "clock's upload profile (upload.per_tile_us, upload.link_MBps)");
  c->add_option("--store,-s", a->store, "tile store whose page geometry (tile, border, layer 0's channels) is timed")->required();
  c->add_option("--output,-o", a->out, "write the profile (TOML config keys) here (- for stdout); default: print it");
  c->add_option("--batches", a->batches, "pages copied a frame, comma separated")->capture_default_str();
  c->add_option("--tiles", a->tiles, "page payload sides timed, comma separated (default: the store's, half and twice it)");
  c->add_option("--reps", a->reps, "repetitions of each (page size, batch); medians")->capture_default_str();
  c->add_option("--clock", a->clock,
                "fit the profile to: gpu (the GL_TIME_ELAPSED queries, as gl replay's gl.upload_gpu_ms_total) | cpu (the submitting "
                "thread's wall time to glFinish) | auto (gpu when its queries saw the copies, else cpu: llvmpipe)")
      ->capture_default_str();
  c->add_option("--seed", a->seed, "seed of the pages' texels")->capture_default_str();
  c->add_flag("--json", a->json, "print the measurements and both fits as JSON");
  c->add_flag("--quiet,-q", a->quiet, "no progress or table");
  c->callback([a] { gl_cal_cmd::run_upload(*a); });
}

}  // namespace vtsim::cli
