#pragma once
// The standard synthetic traces (docs/traces.md, "Generators"). Every pose is a closed-form
// function of its frame index i (t = i / fps, pos = start + v * t * dir, ...), never an
// accumulated sum, so frame 10^6 is as exact as frame 1 and two runs agree bit for bit.
#include <glm/gtc/quaternion.hpp>
#include <glm/vec2.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "core/registry.h"
#include "core/trace.h"

namespace vtsim {

// The default world: an 8192 m x 8192 m terrain, texture over [0, 8192]^2 m, ground at z = 0.
inline constexpr double kDefaultWorldSize_m = 8192.0;

struct TraceGenParams {
  std::string kind = "walk";   // a name of trace_generators()
  double duration_s = 20.0;    // [0, 1e6]; frames i = 0 .. floor(duration * fps)
  double fps = 60.0;           // (0, 10000]
  double speed_mps = 1.5;      // [0, 1e5]; along the heading (orbit: along the circle)
  double heading_deg = 0.0;    // direction of travel and view at t = 0, counter-clockwise from +x
  double height_m = 1.7;       // camera z (ground plane z = 0)
  double pitch_deg = -15.0;    // view pitch, [-90, 90], up positive (orbit: computed, see below)
  double vfov_deg = 60.0;      // [0.01, 179]
  glm::dvec2 start_m{kDefaultWorldSize_m / 2, kDefaultWorldSize_m / 2};  // x, y at t = 0; orbit: centre
  int image_width = 1920;      // pixels
  int image_height = 1080;
  // turn: the heading turns by turn_deg (counter-clockwise positive) at a constant rate during
  // [event_s, event_s + turn_s]; the walker keeps walking along the current heading.
  double turn_deg = 180.0;
  double turn_s = 0.5;         // > 0
  // turn, teleport: when the event starts, seconds from the start, in [0, duration].
  double event_s = 10.0;
  // teleport: from the first frame with t >= event_s on, the position is offset by jump_m along
  // jump_heading_deg (absolute, counter-clockwise from +x): a cut between two frames.
  double jump_m = 2000.0;
  double jump_heading_deg = 90.0;
  // orbit: a circle of radius_m around start_m at height_m, counter-clockwise, looking at the
  // centre on the ground, (start.x, start.y, 0); it starts on the side opposite the heading so
  // that the first view is along heading_deg.
  double radius_m = 50.0;      // > 0
};

// Defaults per kind (docs/traces.md has the table): walk 1.5 m/s at 1.7 m, pitch -15; walk_diagonal
// the same at heading 45; run 5 m/s; drive 20 m/s at 1.5 m; flight 100 m/s at 300 m, pitch -30;
// turn = walk + 180 deg in 0.5 s at 10 s; teleport = walk + 2 km jump north at 10 s; orbit radius
// 50 m at 30 m, one lap in 20 s (5*pi m/s); static at 1.7 m, pitch -15.
// Throws InputError("kind", "unknown trace kind ... did you mean ...") for a name not in the table.
TraceGenParams default_gen_params(std::string_view kind);

// The motion of one kind at time t: the camera's ground position and its orientation. `fixed`
// carries what every frame shares (the heading's direction, the fixed view, the teleport's jump).
struct TraceGenFixed {
  glm::dvec2 dir;      // the heading's unit direction
  glm::dquat q;        // the view at the heading and pitch
  glm::dvec2 jump;     // teleport: the offset after the event
};

// A kind of generated trace (one line each in trace_gen.cpp's table): its defaults over the
// walk's, its own parameters' checks, how its own parameters read in the trace's name, and its
// motion, a closed-form function of t.
struct TraceGenerator {
  std::string_view name;
  std::string_view why;
  void (*defaults)(TraceGenParams& p);          // the kind's defaults, set over TraceGenParams{}'s
  void (*validate)(const TraceGenParams& p);    // its own fields; InputError naming the field
  std::string (*describe)(const TraceGenParams& p);  // its own fields for the trace's name (" radius_m=50")
  void (*pose)(const TraceGenParams& p, const TraceGenFixed& fixed, double t, glm::dvec2& xy, glm::dquat& q);
  // A closed path (the orbit): one lap over the duration unless a speed is given, and a computed
  // pitch (not in the trace's name).
  bool lap = false;
};

// The table, in docs/traces.md's order (walk first: TraceGenParams's defaults).
const Registry<TraceGenerator>& trace_generators();
// The kind of that name; throws InputError(where, "unknown trace kind ... did you mean ...").
const TraceGenerator& find_trace_generator(std::string_view name, const std::string& where);

// Throws InputError("<field>", ...) for a parameter out of range (the field name as in the struct).
Trace generate_trace(const TraceGenParams& p);

// A generator line, as a generated trace's name writes it: "walk duration_s=600 start_m=30,8"
// (the kind, then key=value with the TraceGenParams field names; start_m=X,Y, image=WxH). Keys
// not given keep the kind's defaults; an orbit keeps one lap per duration unless speed_mps is
// given, as `vtsim trace gen`. Throws InputError at `where` for an unknown kind or key, a bad value.
TraceGenParams parse_gen_line(const std::string& line, const std::string& where);

}  // namespace vtsim
