#include "sim/trace/trace_gen.h"

#include <fmt/core.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <charconv>
#include <iterator>

#include <cmath>
#include <numbers>

#include "core/error.h"
#include "sim/trace/trace_io.h"
#include "sim/trace/trace_resample.h"
#include "sim/trace/trace_transform.h"

namespace vtsim {

namespace {

constexpr double kPi = std::numbers::pi;

// (cos, sin) of an angle in degrees, exact at multiples of 90 degrees (a walk due north must not
// drift east by cos(pi/2) = 6e-17 per metre) and symmetric at odd multiples of 45 (the diagonal
// walk stays on x = y; cos(pi/4) and sin(pi/4) differ by an ulp in double).
glm::dvec2 dir_deg(double deg) {
  double r = std::fmod(deg, 360.0);
  if (r < 0) r += 360.0;
  if (r == 0.0) return {1.0, 0.0};
  if (r == 90.0) return {0.0, 1.0};
  if (r == 180.0) return {-1.0, 0.0};
  if (r == 270.0) return {0.0, -1.0};
  const double h = std::sqrt(0.5);
  if (r == 45.0) return {h, h};
  if (r == 135.0) return {-h, h};
  if (r == 225.0) return {-h, -h};
  if (r == 315.0) return {h, -h};
  const double a = r * (kPi / 180.0);
  return {std::cos(a), std::sin(a)};
}

void need(bool ok, const char* field, double v, std::string_view rule) {
  if (!ok) throw InputError(field, fmt::format("{} {}", v, rule));
}

void validate(const TraceGenParams& p) {
  need(std::isfinite(p.duration_s) && p.duration_s >= 0.0 && p.duration_s <= 1e6, "duration_s",
       p.duration_s, "is not in [0, 1e6] s");
  need(std::isfinite(p.fps) && p.fps > 0.0 && p.fps <= 10000.0, "fps", p.fps, "is not in (0, 10000]");
  need(p.duration_s * p.fps + 1.0 <= static_cast<double>(kMaxTraceFrames), "duration_s",
       p.duration_s, fmt::format("at this fps gives more than {} frames", kMaxTraceFrames));
  need(std::isfinite(p.speed_mps) && p.speed_mps >= 0.0 && p.speed_mps <= 1e5, "speed_mps",
       p.speed_mps, "is not in [0, 1e5] m/s");
  need(std::isfinite(p.heading_deg), "heading_deg", p.heading_deg, "is not finite");
  need(std::isfinite(p.height_m) && std::abs(p.height_m) <= 1e7, "height_m", p.height_m,
       "is not in [-1e7, 1e7] m");
  need(std::isfinite(p.pitch_deg) && std::abs(p.pitch_deg) <= 90.0, "pitch_deg", p.pitch_deg,
       "is not in [-90, 90]");
  need(p.vfov_deg >= kMinVfov_deg && p.vfov_deg <= kMaxVfov_deg, "vfov_deg", p.vfov_deg, "is not in [0.01, 179]");
  for (int k = 0; k < 2; ++k)
    need(std::isfinite(p.start_m[k]) && std::abs(p.start_m[k]) <= 1e9, "start_m", p.start_m[k],
         "is not in [-1e9, 1e9] m");
  need(p.image_width >= 1 && p.image_width <= kMaxImageSide, "image_width", p.image_width, "is out of range");
  need(p.image_height >= 1 && p.image_height <= kMaxImageSide, "image_height", p.image_height,
       "is out of range");
  find_trace_generator(p.kind, "kind").validate(p);
}

// The kinds' own checks (validate_trace_gen runs the shared ones first).
void validate_none(const TraceGenParams&) {}

void validate_event(const TraceGenParams& p) {
  need(std::isfinite(p.event_s) && p.event_s >= 0.0 && p.event_s <= p.duration_s, "event_s", p.event_s,
       "is not within [0, duration_s]");
}

void validate_turn(const TraceGenParams& p) {
  need(std::isfinite(p.turn_deg), "turn_deg", p.turn_deg, "is not finite");
  need(std::isfinite(p.turn_s) && p.turn_s > 0.0, "turn_s", p.turn_s, "is not finite and > 0");
  validate_event(p);
}

void validate_teleport(const TraceGenParams& p) {
  validate_event(p);
  need(std::isfinite(p.jump_m) && p.jump_m >= 0.0 && p.jump_m <= 1e9, "jump_m", p.jump_m, "is not in [0, 1e9] m");
  need(std::isfinite(p.jump_heading_deg), "jump_heading_deg", p.jump_heading_deg, "is not finite");
}

void validate_orbit(const TraceGenParams& p) {
  need(std::isfinite(p.radius_m) && p.radius_m > 0.0 && p.radius_m <= 1e9, "radius_m", p.radius_m, "is not in (0, 1e9] m");
}

// Heading (degrees) and planar position of the turn trace at time t: straight, a constant-rate
// turn (the position integrates v * (cos psi, sin psi) in closed form), straight again.
void turn_state(const TraceGenParams& p, double t, double& heading_deg, glm::dvec2& xy) {
  const double v = p.speed_mps;
  const glm::dvec2 d0 = dir_deg(p.heading_deg);
  const double te = p.event_s, tt = p.turn_s;
  if (t < te) {
    heading_deg = p.heading_deg;
    xy = p.start_m + d0 * (v * t);
    return;
  }
  const glm::dvec2 pe = p.start_m + d0 * (v * te);
  const double w = p.turn_deg * (kPi / 180.0) / tt;  // rad/s
  const double psi0 = p.heading_deg * (kPi / 180.0);
  const auto arc = [&](double dt) {  // displacement after dt seconds of turning
    if (w == 0.0) return d0 * (v * dt);
    const double psi = psi0 + w * dt;
    return glm::dvec2(std::sin(psi) - std::sin(psi0), std::cos(psi0) - std::cos(psi)) * (v / w);
  };
  if (t < te + tt) {
    heading_deg = p.heading_deg + p.turn_deg * ((t - te) / tt);
    xy = pe + arc(t - te);
    return;
  }
  heading_deg = p.heading_deg + p.turn_deg;
  xy = pe + arc(tt) + dir_deg(heading_deg) * (v * (t - te - tt));
}

std::string describe(const TraceGenParams& p, const TraceGenerator& g) {
  std::string s = fmt::format("{} duration_s={} fps={} speed_mps={} heading_deg={} height_m={} ", g.name, p.duration_s, p.fps,
                              p.speed_mps, p.heading_deg, p.height_m);
  if (!g.lap) s += fmt::format("pitch_deg={} ", p.pitch_deg);  // a lap's pitch is computed
  s += fmt::format("vfov_deg={} start_m={},{}", p.vfov_deg, p.start_m.x, p.start_m.y);
  return s + g.describe(p);
}

std::string describe_none(const TraceGenParams&) { return {}; }
std::string describe_turn(const TraceGenParams& p) {
  return fmt::format(" turn_deg={} turn_s={} event_s={}", p.turn_deg, p.turn_s, p.event_s);
}
std::string describe_teleport(const TraceGenParams& p) {
  return fmt::format(" jump_m={} jump_heading_deg={} event_s={}", p.jump_m, p.jump_heading_deg, p.event_s);
}
std::string describe_orbit(const TraceGenParams& p) { return fmt::format(" radius_m={}", p.radius_m); }

// The kinds' defaults over TraceGenParams{} (the walk).
void defaults_walk(TraceGenParams&) {}
void defaults_walk_diagonal(TraceGenParams& p) { p.heading_deg = 45.0; }
void defaults_run(TraceGenParams& p) { p.speed_mps = 5.0; }
void defaults_drive(TraceGenParams& p) {
  p.speed_mps = 20.0;
  p.height_m = 1.5;
}
void defaults_flight(TraceGenParams& p) {
  p.speed_mps = 100.0;
  p.height_m = 300.0;
  p.pitch_deg = -30.0;
}
void defaults_orbit(TraceGenParams& p) {
  p.radius_m = 50.0;
  p.height_m = 30.0;
  p.speed_mps = 2.0 * kPi * p.radius_m / p.duration_s;  // one lap in the 20 s trace
}
void defaults_static(TraceGenParams& p) { p.speed_mps = 0.0; }

// The kinds' motion at time t.
void pose_straight(const TraceGenParams& p, const TraceGenFixed& f, double t, glm::dvec2& xy, glm::dquat& q) {
  xy = p.start_m + f.dir * (p.speed_mps * t);
  q = f.q;
}

void pose_teleport(const TraceGenParams& p, const TraceGenFixed& f, double t, glm::dvec2& xy, glm::dquat& q) {
  xy = p.start_m + f.dir * (p.speed_mps * t);
  if (t >= p.event_s) xy += f.jump;
  q = f.q;
}

void pose_turn(const TraceGenParams& p, const TraceGenFixed&, double t, glm::dvec2& xy, glm::dquat& q) {
  double heading = 0.0;
  turn_state(p, t, heading, xy);
  q = yaw_pitch_quat(heading, p.pitch_deg);
}

void pose_orbit(const TraceGenParams& p, const TraceGenFixed&, double t, glm::dvec2& xy, glm::dquat& q) {
  // theta: angle of the camera around the centre; the view points back at the centre.
  const double theta = (p.heading_deg + 180.0) * (kPi / 180.0) + (p.speed_mps / p.radius_m) * t;
  xy = p.start_m + glm::dvec2(std::cos(theta), std::sin(theta)) * p.radius_m;
  const double yaw_deg = theta * (180.0 / kPi) + 180.0;
  const double pitch_deg = -std::atan2(p.height_m, p.radius_m) * (180.0 / kPi);
  q = yaw_pitch_quat(yaw_deg, pitch_deg);
}

}  // namespace

const Registry<TraceGenerator>& trace_generators() {
  static const Registry<TraceGenerator> table(
      "trace kind",
      {
          {"walk", "1.5 m/s at eye height 1.7 m, pitch -15: straight along the heading", defaults_walk, validate_none,
           describe_none, pose_straight, false},
          {"walk_diagonal", "a walk at heading 45 (stays exactly on x = y)", defaults_walk_diagonal, validate_none, describe_none,
           pose_straight, false},
          {"run", "5 m/s, 1.7 m, pitch -15: straight", defaults_run, validate_none, describe_none, pose_straight, false},
          {"drive", "20 m/s, 1.5 m, pitch -15: straight", defaults_drive, validate_none, describe_none, pose_straight, false},
          {"flight", "100 m/s, 300 m, pitch -30: straight", defaults_flight, validate_none, describe_none, pose_straight, false},
          {"turn", "a walk whose heading turns 180 deg in 0.5 s at t = 10 s (a fast turn)", defaults_walk, validate_turn,
           describe_turn, pose_turn, false},
          {"teleport", "a walk that jumps 2000 m north at t = 10 s (a cut)", defaults_walk, validate_teleport, describe_teleport,
           pose_teleport, false},
          {"orbit", "a circle of 50 m around the start point at 30 m, looking at its foot; one lap in 20 s", defaults_orbit,
           validate_orbit, describe_orbit, pose_orbit, true},
          {"static", "1.7 m, pitch -15, no motion", defaults_static, validate_none, describe_none, pose_straight, false},
      });
  return table;
}

const TraceGenerator& find_trace_generator(std::string_view name, const std::string& where) {
  if (const TraceGenerator* g = trace_generators().find(name)) return *g;
  throw InputError(where, trace_generators().unknown(name));
}

TraceGenParams default_gen_params(std::string_view kind) {
  const TraceGenerator& g = find_trace_generator(kind, "kind");
  TraceGenParams p;  // walk
  p.kind = std::string(g.name);
  g.defaults(p);
  return p;
}

Trace generate_trace(const TraceGenParams& p) {
  validate(p);
  Trace trace;
  trace.image_width = p.image_width;
  trace.image_height = p.image_height;
  const TraceGenerator& g = find_trace_generator(p.kind, "kind");
  trace.name = describe(p, g);
  const auto last = static_cast<std::int64_t>(std::floor(p.duration_s * p.fps + 1e-6));
  trace.poses.reserve(static_cast<std::size_t>(last + 1));
  const TraceGenFixed fixed{dir_deg(p.heading_deg), yaw_pitch_quat(p.heading_deg, p.pitch_deg),
                            dir_deg(p.jump_heading_deg) * p.jump_m};
  for (std::int64_t i = 0; i <= last; ++i) {
    Pose pose;
    pose.t_s = static_cast<double>(i) / p.fps;
    pose.vfov_deg = p.vfov_deg;
    glm::dvec2 xy;
    g.pose(p, fixed, pose.t_s, xy, pose.q);
    pose.pos_m = glm::dvec3(xy, p.height_m);
    trace.poses.push_back(pose);
  }
  validate_trace(trace, "generate_trace");
  return trace;
}

}  // namespace vtsim

namespace vtsim {

namespace {

// "a<sep>b" -> two finite doubles, or InputError naming the key.
glm::dvec2 parse_pair(const std::string& s, char sep, const std::string& where, const std::string& key) {
  const std::size_t k = s.find(sep);
  double v[2] = {0, 0};
  const std::string parts[2] = {s.substr(0, k), k == std::string::npos ? std::string() : s.substr(k + 1)};
  for (int i = 0; i < 2; ++i) {
    const auto [p, ec] = std::from_chars(parts[i].data(), parts[i].data() + parts[i].size(), v[i]);
    if (k == std::string::npos || parts[i].empty() || ec != std::errc() || p != parts[i].data() + parts[i].size() ||
        !std::isfinite(v[i]))
      throw InputError(where, fmt::format("{}='{}' is not two numbers separated by '{}'", key, s, sep));
  }
  return {v[0], v[1]};
}

}  // namespace

TraceGenParams parse_gen_line(const std::string& line, const std::string& where) {
  std::vector<std::string> tokens;
  for (std::size_t b = 0; b < line.size();) {
    const std::size_t e = line.find_first_of(" \t", b);
    if (e != b) tokens.push_back(line.substr(b, e == std::string::npos ? std::string::npos : e - b));
    if (e == std::string::npos) break;
    b = e + 1;
  }
  if (tokens.empty()) throw InputError(where, "an empty generator line (e.g. \"walk duration_s=600 start_m=30,8\")");
  const TraceGenerator& g = find_trace_generator(tokens[0], where);
  TraceGenParams p = default_gen_params(g.name);
  // The numeric keys, as TraceGenParams names its fields.
  struct RealKey {
    const char* name;
    double TraceGenParams::*field;
  };
  static constexpr RealKey kReals[] = {
      {"duration_s", &TraceGenParams::duration_s}, {"fps", &TraceGenParams::fps},
      {"speed_mps", &TraceGenParams::speed_mps},   {"heading_deg", &TraceGenParams::heading_deg},
      {"height_m", &TraceGenParams::height_m},     {"pitch_deg", &TraceGenParams::pitch_deg},
      {"vfov_deg", &TraceGenParams::vfov_deg},     {"turn_deg", &TraceGenParams::turn_deg},
      {"turn_s", &TraceGenParams::turn_s},         {"event_s", &TraceGenParams::event_s},
      {"jump_m", &TraceGenParams::jump_m},         {"jump_heading_deg", &TraceGenParams::jump_heading_deg},
      {"radius_m", &TraceGenParams::radius_m}};
  std::vector<const char*> names;
  for (const RealKey& r : kReals) names.push_back(r.name);
  bool duration = false, speed = false, radius = false;
  for (std::size_t i = 1; i < tokens.size(); ++i) {
    const std::size_t eq = tokens[i].find('=');
    if (eq == std::string::npos || eq == 0)
      throw InputError(where, fmt::format("'{}' is not key=value (keys: {}, start_m, image)", tokens[i], fmt::join(names, ", ")));
    const std::string key = tokens[i].substr(0, eq), value = tokens[i].substr(eq + 1);
    if (key == "start_m") {
      p.start_m = parse_pair(value, ',', where, key);
      continue;
    }
    if (key == "image") {
      const glm::dvec2 wh = parse_pair(value, 'x', where, key);
      if (wh.x != std::floor(wh.x) || wh.y != std::floor(wh.y) || wh.x < 1 || wh.y < 1 || wh.x > 65536 || wh.y > 65536)
        throw InputError(where, fmt::format("image='{}': sides must be integers in [1, 65536]", value));
      p.image_width = static_cast<int>(wh.x);
      p.image_height = static_cast<int>(wh.y);
      continue;
    }
    const RealKey* r = std::find_if(std::begin(kReals), std::end(kReals), [&](const RealKey& k) { return key == k.name; });
    if (r == std::end(kReals))
      throw InputError(where, fmt::format("unknown generator key '{}' (keys: {}, start_m, image)", key, fmt::join(names, ", ")));
    double x = 0;
    const auto [ptr, ec] = std::from_chars(value.data(), value.data() + value.size(), x);
    if (value.empty() || ec != std::errc() || ptr != value.data() + value.size() || !std::isfinite(x))
      throw InputError(where, fmt::format("{}='{}' is not a finite number", key, value));
    p.*(r->field) = x;
    duration = duration || r->field == &TraceGenParams::duration_s;
    speed = speed || r->field == &TraceGenParams::speed_mps;
    radius = radius || r->field == &TraceGenParams::radius_m;
  }
  // As `vtsim trace gen`: a lap keeps one lap over its duration unless a speed is given.
  if (g.lap && !speed && std::isfinite(p.duration_s) && p.duration_s > 0 && (duration || radius))
    p.speed_mps = 2.0 * std::numbers::pi * p.radius_m / (duration ? p.duration_s : default_gen_params(g.name).duration_s);
  return p;
}

}  // namespace vtsim
