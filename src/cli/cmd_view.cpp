// vtsim view: render one feedback frame of a scene and write it as a PNG (docs/view.md).
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "cli/cli_io.h"
#include "cli/commands.h"
#include "cli/config_load.h"
#include "cli/trace_load.h"
#include "core/error.h"
#include "core/camera.h"
#include "stream/system/feedback.h"
#include "sim/view/scene.h"
#include "sim/trace/trace_import.h"
#include "sim/view/view_image.h"
#include "sim/run/replay.h"

namespace vtsim::cli {

namespace {

struct ViewOptions {
  std::string scene = "plane";
  std::string obj, heightmap;
  SceneConfig mesh;  // its mesh_* fields: --mesh-loader, --mesh-unit, --mesh-up, --mesh-uv-set, --mesh-no-uv
  double spacing_m = 8.0, height_scale_m = 1.0, z0_m = 0.0;
  unsigned long long seed = 1;
  double terrain_size_m = 8192.0, texels_per_m = 128.0;
  std::string pos = "4096,4096,1.7";
  bool agl = false, allow_repairs = false;
  double yaw = 0.0, pitch = -10.0, roll = 0.0, vfov = 60.0;
  std::string size = "1920x1080";
  int divisor = 8;
  float lod_bias = 0.0f;
  float aniso = 0.0f;
  double near_m = 0.05, far_m = 1.0e7;
  int tile_size = 128;
  std::string out = "view.png";
  int zoom = 1;
  bool seams = false;
  std::string trace;       // take the pose (and image size) from this trace ...
  int frame = -1;          // ... at this frame index
  double time_s = -1.0;    // ... or at this time (interpolated)
  bool size_given = false;
  bool json = false;       // print the results as JSON on stdout instead of the text
  std::vector<std::string> configs, sets;  // -c / --set: the scene and [view] of a replay config
  std::set<std::string> given;             // the flags the command line gave (they win over the config)
};

glm::dvec3 parse_pos(const std::string& s) {
  glm::dvec3 p;
  const char* c = s.c_str();
  for (int k = 0; k < 3; ++k) {
    char* end = nullptr;
    p[k] = std::strtod(c, &end);
    if (end == c || !std::isfinite(p[k])) throw InputError("--pos", "expected x,y,z in metres, got '" + s + "'");
    c = end;
    if (k < 2) {
      if (*c != ',') throw InputError("--pos", "expected x,y,z in metres, got '" + s + "'");
      ++c;
    }
  }
  if (*c != '\0') throw InputError("--pos", "expected x,y,z in metres, got '" + s + "'");
  return p;
}

void parse_view_size(const std::string& s, int& w, int& h) {
  char x = 0;
  char* end = nullptr;
  const long a = std::strtol(s.c_str(), &end, 10);
  if (end == s.c_str() || (*end != 'x' && *end != 'X')) throw InputError("--size", "expected WxH, got '" + s + "'");
  x = *end;
  const char* rest = end + 1;
  const long b = std::strtol(rest, &end, 10);
  if (end == rest || *end != '\0' || a < 1 || b < 1 || a > kMaxImageSide || b > kMaxImageSide)
    throw InputError("--size", "expected WxH with sides in 1.." + std::to_string(kMaxImageSide) + ", got '" + s + "'");
  (void)x;
  w = static_cast<int>(a);
  h = static_cast<int>(b);
}

// What `vtsim view` renders: the scene, the view parameters and the tile size, from the flags, or
// from the replay config given (-c / --set) with the flags given on top.
struct ViewSetup {
  SceneConfig cfg;
  ViewParams vp;
  int tile_size = 0;
  bool from_config = false;
};

ViewSetup view_setup(const ViewOptions& o) {
  ViewSetup v;
  SceneConfig& cfg = v.cfg;
  ViewParams& vp = v.vp;
  int& tile_size = v.tile_size;
  cfg = o.mesh;  // the --mesh-* flags; every other field is set below
  tile_size = o.tile_size;
  const bool from_config = v.from_config = !o.configs.empty() || !o.sets.empty();
  if (!from_config) {
    cfg.kind = find_scene(o.scene).name;
    cfg.size_x_m = cfg.size_y_m = o.terrain_size_m;
    cfg.texels_per_m = o.texels_per_m;
    cfg.file = find_scene(cfg.kind).file_kind == SceneFile::mesh ? o.obj : o.heightmap;  // the two options predate SceneConfig::file
    cfg.spacing_m = o.spacing_m;
    cfg.height_scale_m = o.height_scale_m;
    cfg.z0_m = o.z0_m;
    cfg.seed = o.seed;
    vp.divisor = o.divisor;
    vp.lod_bias = o.lod_bias;
    vp.anisotropic = o.aniso > 0.0f;
    if (vp.anisotropic) vp.max_aniso = o.aniso;
    vp.near_m = o.near_m;
    vp.far_m = o.far_m;
  } else {  // the replay's scene, [view] and tile size; a flag given on the command line wins
    const ReplayConfig rc = load_cli_config(o.configs, o.sets, "", o.trace == "-");
    const auto given = [&](const char* flag) { return o.given.count(flag) > 0; };
    cfg = scene_config_of(rc);
    if (given("--scene")) cfg.kind = find_scene(o.scene).name;
    if (given("--terrain-size")) cfg.size_x_m = cfg.size_y_m = o.terrain_size_m;
    if (given("--texels-per-m")) cfg.texels_per_m = o.texels_per_m;
    const bool mesh_file = find_scene(cfg.kind).file_kind == SceneFile::mesh;
    if (mesh_file ? given("--obj") : given("--heightmap")) cfg.file = mesh_file ? o.obj : o.heightmap;
    if (given("--spacing")) cfg.spacing_m = o.spacing_m;
    if (given("--height-scale")) cfg.height_scale_m = o.height_scale_m;
    if (given("--z0")) cfg.z0_m = o.z0_m;
    if (given("--seed")) cfg.seed = o.seed;
    if (given("--mesh-loader")) cfg.mesh_loader = o.mesh.mesh_loader;
    if (given("--mesh-unit")) cfg.mesh_unit_m = o.mesh.mesh_unit_m;
    if (given("--mesh-up")) cfg.mesh_up = o.mesh.mesh_up;
    if (given("--mesh-uv-set")) cfg.mesh_uv_set = o.mesh.mesh_uv_set;
    if (given("--mesh-no-uv")) cfg.mesh_no_uv = o.mesh.mesh_no_uv;
    if (given("--mesh-planar")) cfg.mesh_planar_m = o.mesh.mesh_planar_m;
    vp = view_params(rc.view);
    if (given("--divisor")) vp.divisor = o.divisor;
    if (given("--lod-bias")) vp.lod_bias = o.lod_bias;
    if (given("--aniso")) {
      vp.anisotropic = o.aniso > 0.0f;
      if (vp.anisotropic) vp.max_aniso = o.aniso;
    }
    if (given("--near")) vp.near_m = o.near_m;
    if (given("--far")) vp.far_m = o.far_m;
    if (!given("--tile-size")) tile_size = rc.texture.tile_size;
  }
  return v;
}

void run_view(const ViewOptions& o) {
  check_output("--out", o.out);  // before the work
  ViewSetup setup = view_setup(o);
  SceneConfig& cfg = setup.cfg;
  const ViewParams& vp = setup.vp;
  const int tile_size = setup.tile_size;
  const bool from_config = setup.from_config;
  if (o.zoom < 1 || o.zoom > 64) throw InputError("--zoom", "must be in [1, 64]");
  // Checked whether or not the scene reads them (the generated heightfield has no height scale).
  if (!(o.spacing_m > 0.0) || !std::isfinite(o.spacing_m)) throw InputError("--spacing", "must be finite and > 0");
  if (!std::isfinite(o.height_scale_m)) throw InputError("--height-scale", "must be finite");
  if (!std::isfinite(o.z0_m)) throw InputError("--z0", "must be finite");

  int width = 0, height = 0;
  parse_view_size(o.size, width, height);
  glm::dvec3 pos = parse_pos(o.pos);

  const auto t_build = std::chrono::steady_clock::now();
  std::unique_ptr<IScene> scene;
  try {
    scene = make_scene(cfg);
  } catch (const InputError& e) {  // the config key, as the user typed it here
    if (from_config) throw;          // the config's key names it
    static const std::pair<const char*, const char*> kMeshFlags[] = {
        {"mesh_loader", "--mesh-loader"}, {"mesh_unit_m", "--mesh-unit"},  {"mesh_up", "--mesh-up"},
        {"mesh_uv_set", "--mesh-uv-set"}, {"mesh_no_uv", "--mesh-no-uv"}, {"mesh_planar_m", "--mesh-planar"}};
    for (const auto& [field, flag] : kMeshFlags)
      if (e.where() == field) throw InputError(flag, std::string(e.what()).substr(e.where().size() + 2));
    if (e.where() != "scene.file") throw;
    throw InputError(find_scene(cfg.kind).file_kind == SceneFile::mesh ? "--obj" : "--heightmap",
                     std::string(e.what()).substr(e.where().size() + 2));
  }
  for (const std::string& w : scene->load_warnings()) warn(w);
  const std::string scene_name = from_config ? cfg.kind : o.scene;
  const double build_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_build).count();
  if (o.agl) {
    double ground = 0.0;
    if (const std::optional<double> z = scene->ground_z(pos.x, pos.y)) {
      ground = *z;
      if (!std::isfinite(ground)) throw InputError("--agl", "the position is outside the heightfield");
    }
    pos.z += ground;
  }

  Pose pose = pose_from_angles(pos, o.yaw, o.pitch, o.roll, o.vfov);
  if (o.trace.empty() && (o.frame >= 0 || o.time_s >= 0))
    throw InputError(o.frame >= 0 ? "--frame" : "--time", "picks a pose of --trace: give the trace too");
  if (!o.trace.empty()) {
    const Trace tr = load_cli_trace(o.trace, o.allow_repairs);
    if (o.frame >= 0 && o.time_s >= 0) throw InputError("--frame", "give --frame or --time, not both");
    if (o.frame >= static_cast<int>(tr.poses.size()))
      throw InputError("--frame", fmt::format("{} is past the trace's last frame {}", o.frame, tr.poses.size() - 1));
    pose = o.time_s >= 0 ? trace_pose_at(tr, o.time_s) : trace_pose(tr, o.frame < 0 ? 0 : o.frame);
    if (!o.size_given) {
      width = tr.image_width;
      height = tr.image_height;
    }
    pos = pose.pos_m;
  }
  const Camera cam = make_camera(pose, width, height);

  ViewBuffer vb;
  const auto t0 = std::chrono::steady_clock::now();
  scene->render(cam, vp, vb);
  const auto t1 = std::chrono::steady_clock::now();
  const TextureExtent ext = scene->texture();
  const int levels = mip_level_count(ext);
  std::vector<TileUse> tiles;
  aggregate_feedback(vb, tile_size, levels, tiles);
  const auto t2 = std::chrono::steady_clock::now();
  const std::size_t seam_tiles = o.seams ? add_level_seams(vb, tile_size, levels, tiles) : 0;
  write_level_image(o.out, vb, levels, o.zoom);

  const double pixels = static_cast<double>(vb.width) * vb.height;
  const ViewCounters& c = vb.counters;
  std::vector<std::uint64_t> per_level(static_cast<std::size_t>(levels), 0), tiles_per_level(static_cast<std::size_t>(levels), 0);
  for (const ViewSample& s : vb.samples) ++per_level[static_cast<std::size_t>(desired_level(s.lod, levels))];
  for (const TileUse& t : tiles) ++tiles_per_level[t.key.level()];
  const double render_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  const double aggregate_ms = std::chrono::duration<double, std::milli>(t2 - t1).count();
  if (o.json) {
    nlohmann::json j;
    j["scene"] = {{"kind", scene_name}, {"texture", {ext.width, ext.height}}, {"levels", levels}, {"build_ms", build_ms}};
    j["camera"] = {{"pos_m", {pos.x, pos.y, pos.z}}, {"fwd", {cam.fwd.x, cam.fwd.y, cam.fwd.z}}, {"vfov_deg", cam.vfov_deg()},
                   {"hfov_deg", cam.hfov_deg()}, {"image", {width, height}}};
    if (!o.trace.empty()) j["camera"]["trace"] = {{"path", o.trace}, {"t_s", pose.t_s}};
    j["buffer"] = {{"size", {vb.width, vb.height}}, {"divisor", vb.divisor}, {"samples", vb.samples.size()}, {"sky", c.sky},
                   {"clipped", c.clipped}, {"backfacing", c.backfacing}, {"outside_texture", c.outside_texture},
                   {"untextured", c.untextured}};
    j["tiles"] = {{"tile_size", tile_size}, {"touched", tiles.size()}, {"level_seam", seam_tiles}};
    nlohmann::json lv = nlohmann::json::array();
    for (int l = 0; l < levels; ++l)
      if (per_level[static_cast<std::size_t>(l)] > 0)
        lv.push_back({{"level", l}, {"samples", per_level[static_cast<std::size_t>(l)]}, {"tiles", tiles_per_level[static_cast<std::size_t>(l)]}});
    j["levels"] = lv;
    j["time_ms"] = {{"render", render_ms}, {"aggregate", aggregate_ms}};
    j["image"] = o.out;
    fmt::print("{}\n", j.dump(2));
    return;
  }
  fmt::print("scene {}: texture {}x{} texels, {} levels (built in {:.1f} ms)\n", scene_name, ext.width, ext.height, levels,
             build_ms);
  if (o.trace.empty())
    fmt::print("camera ({:.3f}, {:.3f}, {:.3f}) m, yaw {} pitch {} roll {} deg, vfov {} (hfov {:.2f}) deg, image {}x{}\n",
               pos.x, pos.y, pos.z, o.yaw, o.pitch, o.roll, o.vfov, cam.hfov_deg(), width, height);
  else
    fmt::print("camera from {} at t = {:.3f} s: ({:.3f}, {:.3f}, {:.3f}) m, looking ({:.3f}, {:.3f}, {:.3f}), vfov {:.1f} deg, "
               "image {}x{}\n", o.trace, pose.t_s, pos.x, pos.y, pos.z, cam.fwd.x, cam.fwd.y, cam.fwd.z, cam.vfov_deg(),
               width, height);
  fmt::print("buffer {}x{} (divisor {}): samples {} ({:.1f} %), sky {}, clipped {}, backfacing {}, "
             "outside texture {}, untextured {}\n",
             vb.width, vb.height, vb.divisor, vb.samples.size(), 100.0 * static_cast<double>(vb.samples.size()) / pixels,
             c.sky, c.clipped, c.backfacing, c.outside_texture, c.untextured);
  if (o.seams)
    fmt::print("touched tiles ({} texels): {} ({} sampled + {} level-seam tiles)\n", tile_size, tiles.size(),
               tiles.size() - seam_tiles, seam_tiles);
  else
    fmt::print("touched tiles ({} texels): {}\n", tile_size, tiles.size());
  for (int l = 0; l < levels; ++l)
    if (per_level[static_cast<std::size_t>(l)] > 0)
      fmt::print("  level {:2}: {:8} samples {:6} tiles\n", l, per_level[static_cast<std::size_t>(l)],
                 tiles_per_level[static_cast<std::size_t>(l)]);
  fmt::print("render {:.3f} ms, aggregate {:.3f} ms\n", render_ms, aggregate_ms);
  fmt::print("wrote {} ({}x{}: colour = desired level, level 0 red, then orange, yellow, lime, green, cyan, "
             "blue, purple, magenta, pink, brown, white, repeating; black = no sample)\n",
             o.out, vb.width * o.zoom, vb.height * o.zoom);
}

}  // namespace

void register_view_commands(CLI::App& app) {
  auto opt = std::make_shared<ViewOptions>();
  auto* cmd = app.add_subcommand("view", "Render one feedback frame of a scene; write the desired mip level as a PNG");
  cmd->add_option("--scene", opt->scene, scenes().names(" | "))->capture_default_str();
  cmd->add_option("--obj", opt->obj, "mesh file (scene mesh): OBJ (vt in [0,1) spans the texture) or any format assimp reads (glTF, FBX, Collada, .pk3; docs/view.md \"Scenes\")");
  cmd->add_option("--mesh-loader", opt->mesh.mesh_loader, "mesh: auto | assimp | obj (scene.mesh_loader)")->capture_default_str();
  cmd->add_option("--mesh-unit", opt->mesh.mesh_unit_m, "mesh (assimp): metres per file unit; Quake 3: 0.0254")->capture_default_str();
  cmd->add_option("--mesh-up", opt->mesh.mesh_up, "mesh (assimp): the file's up axis, auto | y | z")->capture_default_str();
  cmd->add_option("--mesh-uv-set", opt->mesh.mesh_uv_set, "mesh (assimp): UV channel")->capture_default_str();
  cmd->add_option("--mesh-no-uv", opt->mesh.mesh_no_uv, "mesh (assimp): untextured | skip | planar | error")->capture_default_str();
  cmd->add_option("--mesh-planar", opt->mesh.mesh_planar_m, "mesh (assimp), --mesh-no-uv planar: metres per UV period")->capture_default_str();
  cmd->add_option("--heightmap", opt->heightmap, "heightmap image (scene heightfield); default: generated noise");
  cmd->add_option("--spacing", opt->spacing_m, "heightfield post spacing, m")->capture_default_str();
  cmd->add_option("--height-scale", opt->height_scale_m, "metres per heightmap value")->capture_default_str();
  cmd->add_option("--z0", opt->z0_m, "heightfield height of value 0, m")->capture_default_str();
  cmd->add_option("--seed", opt->seed, "generated heightfield / town seed")->capture_default_str();
  cmd->add_option("--terrain-size", opt->terrain_size_m, "terrain (texture) side, m")->capture_default_str();
  cmd->add_option("--texels-per-m", opt->texels_per_m, "level-0 texel density")->capture_default_str();
  cmd->add_option("--pos", opt->pos, "camera position x,y,z, m")->capture_default_str();
  cmd->add_flag("--agl", opt->agl, "z of --pos is above the ground under the camera");
  cmd->add_option("--yaw", opt->yaw, "heading, degrees counter-clockwise from +x")->capture_default_str();
  cmd->add_option("--pitch", opt->pitch, "degrees above the horizon")->capture_default_str();
  cmd->add_option("--roll", opt->roll, "degrees, right side down")->capture_default_str();
  cmd->add_option("--vfov", opt->vfov, "vertical field of view, degrees")->capture_default_str();
  cmd->add_option("--size", opt->size, "full-resolution image WxH")->capture_default_str()->each([opt](const std::string&) {
    opt->size_given = true;
  });
  cmd->add_option("--trace", opt->trace, "take the camera from this trace (pose, vfov, image size)");
  cmd->add_flag("--allow-repairs", opt->allow_repairs, kAllowRepairsHelp);
  cmd->add_option("--frame", opt->frame, "frame index of --trace (default 0)")->check(CLI::Range(0, 1 << 30));
  cmd->add_option("--time", opt->time_s, "time in --trace, s (interpolated)")
      ->check(CLI::Validator(
          [](std::string& v) {
            const double t = std::strtod(v.c_str(), nullptr);
            return std::isfinite(t) && t >= 0.0 ? std::string() : "must be a finite time >= 0 s, not '" + v + "'";
          },
          "TIME>=0"));
  cmd->add_option("--divisor", opt->divisor, "feedback buffer = image / divisor")->capture_default_str();
  cmd->add_option("--lod-bias", opt->lod_bias, "added to every LOD")->capture_default_str();
  cmd->add_option("--aniso", opt->aniso, "anisotropic LOD with this max ratio (0: isotropic)")->capture_default_str();
  cmd->add_option("--near", opt->near_m, "near plane, m (view depth)")->capture_default_str();
  cmd->add_option("--far", opt->far_m, "far plane, m (view depth)")->capture_default_str();
  cmd->add_option("--tile-size", opt->tile_size, "tile payload size for the touched-tile count, texels")
      ->capture_default_str();
  cmd->add_option("-o,--out", opt->out, "output PNG (any format OpenImageIO writes)")->capture_default_str();
  cmd->add_flag("--json", opt->json, "print the results as JSON on stdout instead of the text");
  cmd->add_flag("--seams", opt->seams, "also count level-seam tiles (add_level_seams)");
  cmd->add_option("--zoom", opt->zoom, "upscale the buffer image by this factor")->capture_default_str();
  add_config_options(cmd, opt->configs, opt->sets,
                     "; view reads [scene], [view], texture.tile_size and the texture's size, a flag given wins");
  cmd->callback([opt, cmd]() {
    opt->given = flags_given(cmd);
    try {
      run_view(*opt);
    } catch (const std::invalid_argument& e) {
      throw InputError("view", e.what());
    }
  });
}

}  // namespace vtsim::cli
