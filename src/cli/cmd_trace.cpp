// vtsim trace …: generate, import, export, resample and inspect camera traces (docs/traces.md).
#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <numbers>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "cli/cli_io.h"
#include "cli/commands.h"
#include "cli/trace_load.h"
#include "core/error.h"
#include "core/text.h"
#include "sim/trace/trace_export.h"
#include "sim/trace/trace_format.h"
#include "sim/trace/trace_gen.h"
#include "sim/trace/trace_import.h"
#include "sim/trace/trace_io.h"
#include "sim/trace/trace_resample.h"
#include "sim/trace/trace_stats.h"
#include "sim/view/level_walk.h"
#include "sim/view/mesh.h"
#include "sim/view/mesh_import.h"
#include "sim/view/q3_entities.h"
#include "sim/view/scene.h"

namespace vtsim::cli {

namespace {

// "a,b,c" -> n finite doubles; InputError naming the option otherwise.
std::vector<double> parse_list(const std::string& s, std::size_t n, char sep, const std::string& opt) {
  std::vector<double> v;
  std::size_t b = 0;
  for (;;) {
    const std::size_t e = s.find(sep, b);
    const std::string tok = s.substr(b, e == std::string::npos ? std::string::npos : e - b);
    double x = 0.0;
    if (!text::parse_whole(tok, x) || !std::isfinite(x))
      throw InputError(opt, fmt::format("'{}' is not {} finite numbers separated by '{}'", s, n, sep));
    v.push_back(x);
    if (e == std::string::npos) break;
    b = e + 1;
  }
  if (v.size() != n)
    throw InputError(opt, fmt::format("'{}' is not {} numbers separated by '{}'", s, n, sep));
  return v;
}

void parse_image(const std::string& s, int& w, int& h) {
  const std::vector<double> v = parse_list(s, 2, 'x', "--image");
  for (double x : v)
    if (x != std::floor(x) || x < 1 || x > kMaxImageSide)
      throw InputError("--image", fmt::format("'{}': sides must be integers in [1, {}]", s, kMaxImageSide));
  w = static_cast<int>(v[0]);
  h = static_cast<int>(v[1]);
}

GapPolicy parse_gap_policy(const std::string& s) {
  if (s == "interpolate") return GapPolicy::interpolate;
  if (s == "hold") return GapPolicy::hold;
  if (s == "error") return GapPolicy::error;
  throw InputError("--gap-policy", fmt::format("'{}' is not interpolate, hold or error", s));
}

std::string repairs_text(const TraceRepairs& r) {
  std::vector<std::string> parts;
  if (r.quats_renormalised) parts.push_back(fmt::format("{} quaternions renormalised", r.quats_renormalised));
  if (r.duplicate_times_dropped)
    parts.push_back(fmt::format("{} poses with a repeated time dropped", r.duplicate_times_dropped));
  if (r.rotations_orthonormalised)
    parts.push_back(fmt::format("{} rotations orthonormalised", r.rotations_orthonormalised));
  if (parts.empty()) return "none";
  std::string s = parts[0];
  for (std::size_t i = 1; i < parts.size(); ++i) s += "; " + parts[i];
  return s;
}

nlohmann::json repairs_json(const TraceRepairs& r) {
  return {{"quats_renormalised", r.quats_renormalised},
          {"duplicate_times_dropped", r.duplicate_times_dropped},
          {"rotations_orthonormalised", r.rotations_orthonormalised}};
}

// "native ENU/FLU, tum z-up/optical, ...": each format's default source axes, in table order.
std::string default_axes_text() {
  std::string s;
  for (const TraceFormat& f : trace_formats().entries())
    s += fmt::format("{}{} {}/{}", s.empty() ? "" : ", ", f.name, f.axes.world, f.axes.camera);
  return s;
}

// Options shared by `import` and `info` for reading a non-native file.
struct ReadArgs {
  std::string format = "auto";
  std::string times;
  double rate = 0.0;
  bool strict = false, allow_repairs = false;

  void add(CLI::App* c) {
    c->add_option("--format", format, "Input format: auto, " + trace_formats().names())->capture_default_str();
    c->add_option("--times", times, "KITTI: file with one time in seconds per pose");
    c->add_option("--rate", rate, "KITTI: fixed pose rate in Hz (KITTI odometry is 10)");
    c->add_flag("--strict", strict, "Refuse repairable input (renormalised quaternions, repeated times)");
    c->add_flag("--allow-repairs", allow_repairs, kAllowRepairsHelp);
  }
  ImportOptions options() const {
    ImportOptions o;
    if (format != "auto") o.format = parse_trace_format(format, "--format").name;
    o.kitti_times_path = times;
    o.kitti_rate_hz = rate;
    o.read.strict = strict;
    o.read.allow_repairs = allow_repairs;
    return o;
  }
};

void register_gen(CLI::App* trace) {
  struct Args {
    std::string kind, out;
    double duration = 0, fps = 0, speed = 0, heading = 0, height = 0, pitch = 0, vfov = 0;
    double turn = 0, turn_time = 0, at = 0, jump = 0, jump_heading = 0, radius = 0;
    std::string start, image;
  };
  auto a = std::make_shared<Args>();
  auto* c = trace->add_subcommand("gen", "Generate a standard synthetic trace");
  c->footer(
      "Kinds and their defaults (all start at the terrain centre (4096, 4096), heading 0 = +x,\n"
      "20 s at 60 Hz, 1920x1080, vfov 60):\n"
      "  walk           1.5 m/s, eye height 1.7 m, pitch -15\n"
      "  walk_diagonal  walk at heading 45\n"
      "  run            5 m/s, 1.7 m, pitch -15\n"
      "  drive          20 m/s, 1.5 m, pitch -15\n"
      "  flight         100 m/s, 300 m, pitch -30\n"
      "  turn           walk; turns 180 deg in 0.5 s at t = 10 s\n"
      "  teleport       walk; jumps 2000 m north (heading 90) at t = 10 s\n"
      "  orbit          radius 50 m around the start point at 30 m, looking at its foot; one lap\n"
      "                 in 20 s (5*pi m/s)\n"
      "  static         1.7 m, pitch -15, no motion\n"
      "Example: vtsim trace gen flight --duration 600 -o flight_10min.csv");
  c->add_option("kind", a->kind, trace_generators().names(", "))
      ->required();
  c->add_option("-o,--output", a->out, "Output native trace (.csv; - for stdout)")->required();
  auto* o_duration = c->add_option("--duration", a->duration, "Length in seconds");
  auto* o_fps = c->add_option("--fps", a->fps, "Frames per second");
  auto* o_speed = c->add_option("--speed", a->speed, "Speed in m/s (orbit: along the circle)");
  auto* o_heading = c->add_option("--heading", a->heading, "Heading in degrees, counter-clockwise from +x (east)");
  auto* o_height = c->add_option("--height", a->height, "Camera height in metres above z = 0");
  auto* o_pitch = c->add_option("--pitch", a->pitch, "Pitch in degrees, up positive (not orbit)");
  auto* o_vfov = c->add_option("--vfov", a->vfov, "Vertical field of view in degrees");
  auto* o_start = c->add_option("--start", a->start, "Start point X,Y in metres (orbit: the centre)");
  auto* o_image = c->add_option("--image", a->image, "Image size WxH in pixels");
  auto* o_turn = c->add_option("--turn", a->turn, "turn: angle in degrees, counter-clockwise positive");
  auto* o_turn_time = c->add_option("--turn-time", a->turn_time, "turn: seconds the turn takes");
  auto* o_at = c->add_option("--at", a->at, "turn, teleport: time of the event in seconds");
  auto* o_jump = c->add_option("--jump", a->jump, "teleport: jump distance in metres");
  auto* o_jump_heading = c->add_option("--jump-heading", a->jump_heading, "teleport: jump direction in degrees");
  auto* o_radius = c->add_option("--radius", a->radius, "orbit: radius in metres");
  c->callback([=] {
    check_output("--output", a->out);  // before the work
    const TraceGenerator& kind = find_trace_generator(a->kind, "kind");
    TraceGenParams p = default_gen_params(kind.name);
    const bool duration_given = o_duration->count() > 0;
    if (duration_given) p.duration_s = a->duration;
    if (o_fps->count()) p.fps = a->fps;
    if (o_speed->count()) p.speed_mps = a->speed;
    else if (kind.lap && duration_given && std::isfinite(p.duration_s) && p.duration_s > 0)
      p.speed_mps = 2.0 * std::numbers::pi * p.radius_m / p.duration_s;  // keep one lap
    if (o_heading->count()) p.heading_deg = a->heading;
    if (o_height->count()) p.height_m = a->height;
    if (o_pitch->count()) p.pitch_deg = a->pitch;
    if (o_vfov->count()) p.vfov_deg = a->vfov;
    if (o_start->count()) {
      const auto v = parse_list(a->start, 2, ',', "--start");
      p.start_m = {v[0], v[1]};
    }
    if (o_image->count()) parse_image(a->image, p.image_width, p.image_height);
    if (o_turn->count()) p.turn_deg = a->turn;
    if (o_turn_time->count()) p.turn_s = a->turn_time;
    if (o_at->count()) p.event_s = a->at;
    if (o_jump->count()) p.jump_m = a->jump;
    if (o_jump_heading->count()) p.jump_heading_deg = a->jump_heading;
    if (o_radius->count()) {
      if (kind.lap && !o_speed->count() && a->radius > 0 && std::isfinite(a->radius))
        p.speed_mps *= a->radius / p.radius_m;  // keep the lap time
      p.radius_m = a->radius;
    }
    Trace t;
    try {
      t = generate_trace(p);
    } catch (const InputError& e) {  // the generator names its parameter; the user typed a flag
      static const std::pair<const char*, const char*> flags[] = {
          {"duration_s", "--duration"}, {"fps", "--fps"},         {"speed_mps", "--speed"},     {"heading_deg", "--heading"},
          {"height_m", "--height"},     {"pitch_deg", "--pitch"}, {"vfov_deg", "--vfov"},       {"start_m", "--start"},
          {"turn_deg", "--turn"},       {"turn_s", "--turn-time"}, {"event_s", "--at"},         {"jump_m", "--jump"},
          {"jump_heading_deg", "--jump-heading"}, {"radius_m", "--radius"}, {"image", "--image"}};
      for (const auto& [field, flag] : flags)
        if (e.where() == field) throw InputError(flag, std::string(e.what()).substr(e.where().size() + 2));
      throw;
    }
    save_trace(t, a->out);
    if (a->out != "-") fmt::print(stderr, "wrote {} poses to {}\n", t.poses.size(), a->out);
  });
}

struct TransformArgs {
  double scale = 1.0, yaw = 0.0, time_scale = 1.0, time_offset = 0.0, vfov = 0.0;
  std::string offset, up, camera, image;
  bool recenter = false, keep_time = false;

  void add(CLI::App* c) {
    c->add_option("--scale", scale, "Multiply positions (room metres -> terrain metres)")->capture_default_str();
    c->add_option("--offset", offset, "Add X,Y,Z metres last (e.g. 4096,4096,300)");
    c->add_flag("--recenter", recenter, "Subtract the first position first (the trace starts at --offset)");
    c->add_option("--yaw", yaw, "Rotate about world +z by degrees, counter-clockwise")->capture_default_str();
    c->add_option("--up", up,
                  "Source world axes: z-up, y-up, y-down (= -y-up, use --up=-y-up), ned, or 3 letters "
                  "of ENWSUD (default: the format's)");
    c->add_option("--camera", camera,
                  "Source camera axes: optical, flu, opengl, imu-urf, or 3 letters of FBLRUD "
                  "(default: the format's)");
    c->add_option("--time-scale", time_scale, "Multiply times (2 = half speed)")->capture_default_str();
    c->add_option("--time-offset", time_offset, "Add seconds to times last")->capture_default_str();
    c->add_flag("--keep-time", keep_time, "Keep source times instead of starting at 0");
    c->add_option("--vfov", vfov, "Vertical field of view in degrees for every pose (default 60; native: kept)");
    c->add_option("--image", image, "Image size WxH in pixels (default 1920x1080; native: kept)");
  }
  void apply(ImportOptions& o) const {
    TraceTransform& tf = o.transform;
    tf.scale = scale;
    if (!offset.empty()) {
      const auto v = parse_list(offset, 3, ',', "--offset");
      tf.offset_m = {v[0], v[1], v[2]};
    }
    tf.recenter = recenter;
    tf.yaw_deg = yaw;
    tf.world_axes = up;
    tf.camera_axes = camera;
    tf.time_scale = time_scale;
    tf.time_offset_s = time_offset;
    tf.rebase_time = !keep_time;
    tf.vfov_deg = vfov;
    if (!image.empty()) parse_image(image, o.image_width, o.image_height);
  }
};

struct ResampleArgs {
  double gap = 0.5;
  std::string policy = "interpolate";
  void add(CLI::App* c) {
    c->add_option("--gap", gap, "An input time step longer than this (s) is a gap")->capture_default_str();
    c->add_option("--gap-policy", policy, "In a gap: interpolate, hold (freeze, then jump) or error")
        ->capture_default_str();
  }
};

void print_resample_report(const ResampleReport& r, double fps, const ResampleArgs& ra) {
  fmt::print(stderr, "resampled to {} Hz: {} frames; {} gaps longer than {} s ({:.6g} s in total, {})\n",
             fps, r.frames, r.gaps, ra.gap, r.gap_time_s, ra.policy);
}

void register_import(CLI::App* trace) {
  struct Args {
    std::string in, out;
    ReadArgs read;
    TransformArgs tf;
    ResampleArgs rs;
    double resample = 0.0;
  };
  auto a = std::make_shared<Args>();
  auto* c = trace->add_subcommand("import", "Convert a TUM, EuRoC or KITTI trajectory to a native trace");
  c->footer(
      "Transform order: time t' = (t - t0) * time-scale + time-offset; position\n"
      "p' = offset + scale * Rz(yaw) * W * (p - [recenter] p0); orientation q' = Rz(yaw) * W * q * C^-1\n"
      "(W: source world axes -> ENU, C: source camera axes -> FLU). Defaults per format:\n" +
      default_axes_text() +
      ".\nExample (a handheld recording flown over the terrain centre at 300 m, 100x larger):\n"
      "  vtsim trace import --format tum --scale 100 --recenter --offset 4096,4096,300 \\\n"
      "      --resample 60 tum_fr1_xyz_groundtruth.txt -o fr1_flight.csv");
  c->add_option("input", a->in, "Input trajectory file (- for stdin)")->required();
  c->add_option("-o,--output", a->out, "Output native trace (- for stdout)")->required();
  a->read.add(c);
  a->tf.add(c);
  c->add_option("--resample", a->resample, "Resample to this frame rate (Hz) after the transform");
  a->rs.add(c);
  c->callback([a] {
    check_output("--output", a->out);  // before the work
    ImportOptions o = a->read.options();
    a->tf.apply(o);
    TraceLoadReport rep;
    Trace t = with_input(a->in, [&](const std::string& in) { return import_trace(in, o, &rep); });
    print_repair_warnings(rep, a->in);
    fmt::print(stderr, "read {} poses ({}, {} lines) from {}; repairs: {}\n", rep.poses, rep.format,
               rep.lines, a->in, repairs_text(rep.repairs));
    if (a->resample != 0.0) {
      ResampleOptions ro;
      ro.fps = a->resample;
      ro.gap_s = a->rs.gap;
      ro.gap_policy = parse_gap_policy(a->rs.policy);
      ResampleReport rr;
      t = resample(t, ro, &rr);
      print_resample_report(rr, ro.fps, a->rs);
    }
    save_trace(t, a->out);
    if (a->out != "-") fmt::print(stderr, "wrote {} poses to {}\n", t.poses.size(), a->out);
  });
}

void register_export(CLI::App* trace) {
  struct Args {
    std::string in, out, format, times, up, camera;
    double rate = 0.0;
    bool allow_repairs = false;
  };
  auto a = std::make_shared<Args>();
  std::string apart;  // "kitti": formats whose poses carry no time
  for (const TraceFormat& f : trace_formats().entries())
    if (f.separate_times) apart += (apart.empty() ? "" : ", ") + std::string(f.name);
  auto* c = trace->add_subcommand("export", "Write a trace in another format (TUM, EuRoC, KITTI), e.g. for evo");
  c->footer(
      "Writes the poses in the format's own conventions and units, so that `vtsim trace import`\n"
      "with the defaults (and the same --times file or --rate) gives the trace back: positions\n"
      "exactly, orientations to ~1e-15, times to the nanosecond, rebased to the first pose; name,\n"
      "image size and vfov only in native. Default axes per format (world/camera):\n" +
      default_axes_text() +
      ".\nExamples (the first for evo_traj tum walk_tum.txt --plot):\n"
      "  vtsim trace export --format tum traces/walk.csv -o walk_tum.txt\n"
      "  vtsim trace export --format kitti traces/walk.csv -o walk_kitti.txt --times walk_times.txt");
  c->add_option("input", a->in, "Input trace (native; other formats are detected and imported with defaults; - for stdin)")
      ->required();
  c->add_option("-o,--output", a->out, "Output file (- for stdout)")->required();
  c->add_option("--format", a->format, "Output format: " + trace_formats().names())->required();
  c->add_option("--times", a->times,
                "Formats whose poses carry no time (" + apart + "): write the times here, one per line in seconds");
  c->add_option("--rate", a->rate,
                "Formats whose poses carry no time (" + apart +
                    "): write no times; the poses must be at t0 + i / rate (Hz), what `import --rate` gives");
  c->add_option("--up", a->up, "World axes to write in, as for import (default: the format's)");
  c->add_option("--camera", a->camera, "Camera axes to write in, as for import (default: the format's)");
  c->add_flag("--allow-repairs", a->allow_repairs, kAllowRepairsHelp);
  c->callback([a] {
    check_output("--output", a->out);  // before the work
    check_output("--times", a->times);
    const TraceFormat& format = parse_trace_format(a->format, "--format");
    const Trace t = load_cli_trace(a->in, a->allow_repairs);
    ExportOptions o;
    o.world_axes = a->up;
    o.camera_axes = a->camera;
    o.times_path = a->times;
    o.rate_hz = a->rate;
    export_trace(t, format.name, a->out, o);
    if (a->out != "-")
      fmt::print(stderr, "wrote {} poses ({}) to {}{}\n", t.poses.size(), format.name, a->out,
                 a->times.empty() || a->times == "-" ? "" : ", their times to " + a->times);
  });
}

void register_resample(CLI::App* trace) {
  struct Args {
    std::string in, out;
    double fps = 0.0;
    ResampleArgs rs;
    bool allow_repairs = false;
  };
  auto a = std::make_shared<Args>();
  auto* c = trace->add_subcommand("resample", "Resample a trace to a fixed frame rate");
  c->footer(
      "Frame k is at t0 + k / fps; positions and vfov interpolate linearly, orientations by\n"
      "shortest-arc slerp. Example: vtsim trace resample --fps 60 recorded.csv -o recorded_60.csv");
  c->add_option("input", a->in, "Input trace (native; other formats are detected and imported with defaults; - for stdin)")
      ->required();
  c->add_option("-o,--output", a->out, "Output native trace (- for stdout)")->required();
  c->add_option("--fps", a->fps, "Output frame rate in Hz")->required();
  a->rs.add(c);
  c->add_flag("--allow-repairs", a->allow_repairs, kAllowRepairsHelp);
  c->callback([a] {
    check_output("--output", a->out);  // before the work
    const Trace in = load_cli_trace(a->in, a->allow_repairs);
    ResampleOptions ro;
    ro.fps = a->fps;
    ro.gap_s = a->rs.gap;
    ro.gap_policy = parse_gap_policy(a->rs.policy);
    ResampleReport rr;
    const Trace t = resample(in, ro, &rr);
    print_resample_report(rr, ro.fps, a->rs);
    save_trace(t, a->out);
  });
}

void register_cut(CLI::App* trace) {
  struct Args {
    std::string in, out;
    double from_s = 0.0, to_s = 0.0;
    bool allow_repairs = false;
  };
  auto a = std::make_shared<Args>();
  auto* c = trace->add_subcommand("cut", "Crop a trace to the poses between two times");
  c->footer(
      "Keeps the poses from --from to --to (seconds, the trace's own times, kept as they are), with a\n"
      "pose interpolated at each end unless one is stored there; writes a native trace.\n"
      "Example: vtsim trace cut walk.csv --from 30 --to 60 -o walk_30_60.csv");
  c->add_option("input", a->in, "Input trace (native; other formats are detected and imported with defaults; - for stdin)")
      ->required();
  c->add_option("-o,--output", a->out, "Output native trace (- for stdout)")->required();
  c->add_option("--from", a->from_s, "Start time, s (at or after the trace's first pose)")->required();
  c->add_option("--to", a->to_s, "End time, s (after --from, at or before the trace's last pose)")->required();
  c->add_flag("--allow-repairs", a->allow_repairs, kAllowRepairsHelp);
  c->callback([a] {
    check_output("--output", a->out);
    const Trace in = load_cli_trace(a->in, a->allow_repairs);
    const Trace t = cut_trace(in, a->from_s, a->to_s);
    save_trace(t, a->out);
    if (a->out != "-")
      fmt::print(stderr, "wrote {} poses ({} s to {} s) to {}\n", t.poses.size(), a->from_s, a->to_s, a->out);
  });
}

void print_events(const char* what, std::int64_t n, const std::vector<TraceEvent>& list) {
  for (const TraceEvent& e : list)
    fmt::print("  {} at pose {} (t = {:.6f} s): {:.6g} m in {:.6g} s\n", what, e.pose, e.t_s,
               e.distance_m, e.dt_s);
  if (static_cast<std::int64_t>(list.size()) < n)
    fmt::print("  ... {} more\n", n - static_cast<std::int64_t>(list.size()));
}

void register_info(CLI::App* trace) {
  struct Args {
    std::string in;
    bool json = false;
    ReadArgs read;
    TraceStatsOptions so;
  };
  auto a = std::make_shared<Args>();
  auto* c = trace->add_subcommand("info", "Duration, rate, path length, speeds, cuts and gaps of a trace");
  c->footer(
      "Any supported format (detected, or --format); non-native files are read with the import\n"
      "defaults (times from 0). Example: vtsim trace info --json traces/walk.csv");
  c->add_option("input", a->in, "Trace file (- for stdin)")->required();
  c->add_flag("--json", a->json, "Print JSON instead of text");
  a->read.add(c);
  c->add_option("--cut-speed", a->so.cut_speed_mps, "A step faster than this (m/s) ...")->capture_default_str();
  c->add_option("--cut-distance", a->so.cut_distance_m, "... and longer than this (m) is a cut")
      ->capture_default_str();
  c->add_option("--gap", a->so.gap_s, "A time step longer than this (s) is a gap")->capture_default_str();
  c->add_option("--min-step", a->so.min_step_s, "Measure speeds over steps at least this long (s; 0: raw steps)")
      ->capture_default_str();
  c->callback([a] {
    TraceLoadReport rep;
    ImportOptions io = a->read.options();
    // A native file is shown as stored; other formats as imported with the defaults.
    const Trace t = with_input(a->in, [&](const std::string& in) {
      if (io.format.empty()) io.format = detect_trace_format(in, io.read.limits);
      return io.format == "native" ? load_trace(in, io.read, &rep) : import_trace(in, io, &rep);
    });
    print_repair_warnings(rep, a->in);
    const TraceStats s = trace_stats(t, a->so);
    if (a->json) {
      nlohmann::json j = to_json(s);
      j["file"] = a->in;
      j["format"] = rep.format;
      j["name"] = t.name;
      j["lines"] = rep.lines;
      j["repairs"] = repairs_json(rep.repairs);
      fmt::print("{}\n", j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace));
      return;
    }
    fmt::print("file:          {} ({}, {} lines)\n", a->in, rep.format, rep.lines);
    fmt::print("name:          {}\n", t.name);
    fmt::print("frames:        {}\n", s.frames);
    fmt::print("duration:      {:.6f} s\n", s.duration_s);
    fmt::print("mean rate:     {:.6g} Hz (step min {:.6g} s, max {:.6g} s)\n", s.mean_rate_hz, s.dt_min_s,
               s.dt_max_s);
    fmt::print("path length:   {:.6g} m\n", s.path_length_m);
    fmt::print("speed:         p50 {:.6g}  p99 {:.6g}  max {:.6g} m/s (over {} steps >= {:g} s)\n",
               s.speed_p50_mps, s.speed_p99_mps, s.speed_max_mps, s.speed_steps, a->so.min_step_s);
    fmt::print("angular speed: max {:.6g} deg/s\n", s.angular_speed_max_dps);
    fmt::print("bounding box:  x [{:.6g}, {:.6g}]  y [{:.6g}, {:.6g}]  z [{:.6g}, {:.6g}] m\n", s.bbox_min_m.x,
               s.bbox_max_m.x, s.bbox_min_m.y, s.bbox_max_m.y, s.bbox_min_m.z, s.bbox_max_m.z);
    fmt::print("image:         {}x{}, vfov {:.6g}..{:.6g} deg\n", s.image_width, s.image_height, s.vfov_min_deg,
               s.vfov_max_deg);
    fmt::print("cuts:          {} (steps > {:g} m at > {:g} m/s)\n", s.cuts, a->so.cut_distance_m,
               a->so.cut_speed_mps);
    print_events("cut", s.cuts, s.cut_list);
    fmt::print("gaps:          {} (steps > {:g} s)\n", s.gaps, a->so.gap_s);
    print_events("gap", s.gaps, s.gap_list);
    fmt::print("repairs:       {}\n", repairs_text(rep.repairs));
  });
}


// The level's mesh in world metres. THE IMPORTER HOOK: today an OBJ (load_obj) whose coordinates
// are in the level's units (Quake units for an OpenArena level exported as it is), scaled by
// unit_m, z up; at the assimp importer's merge this becomes its import_mesh with the same unit
// scale and up axis (a .pk3 level read directly).
// The level's mesh in world metres: an OBJ through load_obj (scaled by unit_m, z up), anything
// else (a Quake 3 .pk3, glTF, ...) through import_mesh with the same scale, its up axis "auto" (z
// for Quake 3, where the entity origins are read). Only the geometry matters to the walk: the
// texture regions are laid out in the default scene's texture.
Mesh lw_load_level_mesh(const std::string& path, double unit_m) {
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext == ".obj" || ext == ".OBJ") {
    ObjStats os;
    Mesh m = load_obj(path, &os);
    for (const std::string& w : obj_warnings(os, path)) warn(w);
    for (glm::dvec3& q : m.positions) q *= unit_m;
    return m;
  }
  MeshImportOptions o;
  o.unit_m = unit_m;
  if (mesh_up_axis(o, path) != "z")
    throw InputError(path, "a level walk reads waypoints in the file's own z-up frame; this file is y-up "
                           "(give --waypoints in world metres and a z-up mesh, or convert it)");
  const SceneConfig defaults;
  const TextureExtent ext_tex = scene_texture(defaults);
  MeshImportStats st;
  Mesh m = import_mesh(path, o, ext_tex.width, ext_tex.height, &st);
  for (const std::string& w : mesh_import_warnings(st, path)) warn(w);
  return m;
}

void register_level_walk(CLI::App* trace) {
  struct Args {
    std::string level, mesh, waypoints, out, image;
    double unit_m = 0.0254;
    bool no_items = false, all_points = false;
    LevelWalkParams p;
  };
  auto a = std::make_shared<Args>();
  auto* c = trace->add_subcommand("level-walk", "A camera walk through a level's spawn points and items");
  c->footer(
      "Waypoints: the spawn points (info_player_*, team_CTF_*) of a Quake 3 level (.bsp, or a .pk3\n"
      "from scripts/fetch_levels.sh) in file order, then its items (weapon_*, item_*, ammo_*),\n"
      "scaled by --unit-m; or --waypoints FILE (x y z per line, world metres) walked in order.\n"
      "The tour starts at the first waypoint with a walkable neighbour and goes to the nearest\n"
      "unvisited one along walkable legs until none is reachable (docs/traces.md, \"Walks through a\n"
      "level\"; docs/levels.md). Example:\n"
      "  scripts/fetch_levels.sh && vtsim trace level-walk build/levels/oa_dm1.bsp \\\n"
      "      --mesh build/levels/oa_dm1.pk3 -o oa_dm1_walk.csv");
  c->add_option("level", a->level, "Quake 3 level (.bsp or .pk3) whose entities give the waypoints");
  c->add_option("--mesh", a->mesh, "The level's geometry, in the level's units (a .pk3 from scripts/fetch_levels.sh, glTF, ... or .obj)")->required();
  c->add_option("-o,--output", a->out, "Output native trace (.csv; - for stdout)")->required();
  c->add_option("--waypoints", a->waypoints, "Walk these points in order instead (x y z per line, metres)");
  c->add_option("--unit-m", a->unit_m, "Metres per level unit (Quake: 1 unit = 1 inch)")->capture_default_str();
  c->add_flag("--no-items", a->no_items, "Spawn points only, not items");
  c->add_flag("--all-entities", a->all_points,
              "Also every other entity with an origin but lights (targets, teleport destinations...): more legs");
  c->add_option("--speed", a->p.speed_mps, "Walking speed, m/s")->capture_default_str();
  c->add_option("--eye", a->p.eye_m, "Eye height above the floor, m")->capture_default_str();
  c->add_option("--duration", a->p.duration_s, "Seconds (0: one tour; longer: back and forth)")->capture_default_str();
  c->add_option("--fps", a->p.fps, "Frames per second")->capture_default_str();
  c->add_option("--pitch", a->p.pitch_deg, "Pitch in degrees, up positive")->capture_default_str();
  c->add_option("--vfov", a->p.vfov_deg, "Vertical field of view in degrees")->capture_default_str();
  c->add_option("--image", a->image, "Image size WxH in pixels (default 1920x1080)");
  c->add_option("--max-leg", a->p.max_leg_m, "Waypoints further apart are not joined directly, m")->capture_default_str();
  c->add_option("--via-grid", a->p.via_grid_m, "Via points on a grid this far apart, m (0: none)")->capture_default_str();
  c->add_option("--max-turn", a->p.max_turn_dps, "Yaw turning rate limit, deg/s")->capture_default_str();
  c->callback([a] {
    check_output("--output", a->out);
    if (!std::isfinite(a->unit_m) || a->unit_m <= 0.0 || a->unit_m > 1e3)
      throw InputError("--unit-m", fmt::format("{} is not in (0, 1000]", a->unit_m));
    if (!a->image.empty()) parse_image(a->image, a->p.image_width, a->p.image_height);
    if (a->level.empty() == a->waypoints.empty())
      throw InputError("level", "give a level (.bsp or .pk3) or --waypoints FILE, one of the two");
    std::vector<glm::dvec3> wp;
    std::size_t spawns = 0, items = 0, others = 0;
    std::vector<std::string> names;  // classname per waypoint (a level's)
    if (!a->waypoints.empty()) {
      wp = read_waypoints(a->waypoints);
      a->p.in_order = true;
    } else {
      const std::vector<Q3Entity> es = read_q3_entities(a->level);
      // Spawn points first (the tour starts at the first one of the largest walkable part).
      for (int pass = 0; pass < 3; ++pass)
        for (const Q3Entity& e : es) {
          const bool spawn = is_q3_spawn(e), item = is_q3_item(e);
          const bool take = pass == 0   ? spawn
                            : pass == 1 ? !a->no_items && item
                                        : a->all_points && !spawn && !item && e.classname != "light";
          if (!e.origin || !take) continue;
          wp.push_back(*e.origin * a->unit_m);
          names.push_back(e.classname);
          ++(pass == 0 ? spawns : pass == 1 ? items : others);
        }
      if (spawns == 0) warn(fmt::format("{}: no spawn point (info_player_*, team_CTF_*)", a->level));
    }
    const Mesh mesh = lw_load_level_mesh(a->mesh, a->unit_m);
    LevelWalkStats st;
    const Trace t = level_walk(mesh, wp, a->p, &st);
    // "item_health (3.2, 4, 0.61) m, ..." for the first 8 waypoints left out for a reason.
    const auto which = [&](const std::vector<std::size_t>& idx) {
      std::string list;
      for (std::size_t k = 0; k < idx.size() && k < 8; ++k) {
        const glm::dvec3& q = wp[idx[k]];
        list += fmt::format("{}{}{}({:.2f}, {:.2f}, {:.2f}) m", k ? ", " : "", names.empty() ? "" : names[idx[k]],
                            names.empty() ? "" : " ", q.x, q.y, q.z);
      }
      return list + (idx.size() > 8 ? ", ..." : "");
    };
    if (st.no_floor)
      warn(fmt::format("{} of {} waypoints have no floor within {} m below them, left out: {}", st.no_floor,
                       st.waypoints, a->p.probe_m, which(st.no_floor_list)));
    if (st.unreachable)
      warn(fmt::format("{} of {} waypoints are not reachable from the start, left out: {}", st.unreachable,
                       st.waypoints, which(st.unreachable_list)));
    save_trace(t, a->out);
    fmt::print(stderr, "legs refused: {} no line of sight, {} no floor within a step, {} no headroom, {} blocked, {} "
               "other level\n", st.refused[0], st.refused[1], st.refused[2], st.refused[3], st.refused[4]);
    fmt::print(stderr,
               "level walk: {} waypoints ({} spawns, {} items, {} others), {} visited; {} via points, {} walkable legs; path {:.1f} m, tour "
               "{:.1f} s; {} triangles, {} raycasts\n",
               st.waypoints, spawns, items, others, st.visited, st.via_points, st.legs, st.path_length_m, st.tour_s, mesh.tris.size(), st.rays);
    if (a->out != "-") fmt::print(stderr, "wrote {} poses ({:.1f} s) to {}\n", t.poses.size(), t.poses.back().t_s, a->out);
  });
}

}  // namespace

void register_trace_commands(CLI::App& app) {
  auto* trace = app.add_subcommand("trace", "Generate, import, export, resample, cut and inspect camera traces");
  trace->require_subcommand(1);
  register_gen(trace);
  register_import(trace);
  register_export(trace);
  register_resample(trace);
  register_cut(trace);
  register_info(trace);
  register_level_walk(trace);
}

}  // namespace vtsim::cli
