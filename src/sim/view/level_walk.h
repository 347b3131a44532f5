#pragma once
// A camera walk through a level (docs/traces.md, "Walks through a level"): waypoints (a Quake 3
// level's spawn points and items, q3_entities.h, or a path the user gives) joined where a walker
// can go straight, visited along shortest paths at walking speed with the eye a fixed height
// above the floor found by raycasts into the level's mesh.
#include <cstddef>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "core/trace.h"
#include "sim/view/mesh.h"

namespace vtsim {

struct LevelWalkParams {
  double speed_mps = 1.5;   // along the ground (horizontal), (0, 100]
  double fps = 60.0;        // (0, 1000]
  double eye_m = 1.7;       // eye above the floor, (0, 100]
  double pitch_deg = 0.0;   // [-90, 90], up positive
  double vfov_deg = 60.0;
  int image_width = 1920, image_height = 1080;
  // 0: the whole tour; > 0: exactly this long, cut short, or walking the tour back and forth.
  double duration_s = 0.0;
  // false: a tour of the largest connected part of the waypoint graph (greedy nearest unvisited
  // by path length, from the part's first waypoint); true: the waypoints walked in the given
  // order, each leg straight.
  bool in_order = false;
  // Walkability (the Quake 3 player's rules, bg_local.h: STEPSIZE 18 units = 0.457 m, walkable
  // surface normals have z >= MIN_WALK_NORMAL 0.7).
  double max_step_m = 0.46;    // largest rise or drop between floor samples
  double min_floor_nz = 0.7;   // a floor's unit normal has |z| >= this (slopes up to 45.6 deg)
  double sample_m = 0.25;      // floor sampled along a leg at most this far apart
  double radius_m = 0.25;      // half-width of the walker: legs are tested this far to each side
  double max_leg_m = 40.0;     // waypoints further apart (horizontally) are not joined directly
  // Via points: floors found on a grid of this spacing (0: none) join waypoints that no straight
  // leg joins; paths through them are pulled straight where a leg allows.
  double via_grid_m = 1.0;    // finds doors 2 m wide (the walker's radius taken off each side)
  double probe_m = 3.0;        // a waypoint's floor is searched this far below it (from 0.1 m above)
  double smooth_m = 0.6;       // the eye follows the floor averaged over this much path (box filter)
  double max_turn_dps = 120.0; // yaw turning rate limit, deg/s
  double look_ahead_m = 0.5;   // the heading aims at the path point this far ahead
};

struct LevelWalkStats {
  std::size_t waypoints = 0;      // given
  std::size_t no_floor = 0;       // without a floor within probe_m below (excluded)
  std::size_t via_points = 0;     // graph nodes from the via grid
  std::size_t legs = 0;           // walkable straight legs found (graph edges, via points' too)
  // Waypoint pairs within max_leg_m refused, by the first reason found: no line of sight at eye height, no
  // floor within the step limit, no headroom, blocked (knee or eye height, centre or sides), the
  // floor ends at another level than the far waypoint's.
  std::size_t refused[5] = {0, 0, 0, 0, 0};
  std::size_t visited = 0;        // waypoints the walk passes
  std::size_t unreachable = 0;    // with a floor, outside the walked part of the graph (excluded)
  std::vector<std::size_t> order; // waypoints in the order the walk reaches them (indices)
  std::vector<std::size_t> no_floor_list, unreachable_list;  // the waypoints left out (indices)
  double path_length_m = 0.0;     // of the tour, 3-D along the floor samples, metres
  double tour_s = 0.0;            // one pass of the tour (horizontal length / speed_mps), seconds
  std::size_t rays = 0;           // raycasts made (segments and downward probes)
  std::size_t grid_cells = 0;     // cells of the raycasting grid
};

// The walk. Poses: t = i / fps; the position is a closed-form function of the path and i (arc
// length s = speed * t, linear interpolation between floor samples, eye_m above the floor averaged
// over smooth_m of path); the heading turns toward the path point look_ahead_m ahead at most
// max_turn_dps (a sequential filter: deterministic, not closed form). Bit-for-bit reproducible.
// Cost: a raycasting grid over the triangles (level_walk.cpp: about 2 cells per triangle), then
// ~8 rays per 0.25 m of each leg tried: waypoint pairs within max_leg_m, via points to their 8
// neighbour columns, waypoints to the via points within 2 columns; one Dijkstra (binary heap) per
// waypoint visited. oa_dm1 (7.5 k triangles, 39 waypoints, 2.5 k via points): 0.4 M rays, 0.09 s.
// Throws InputError("level_walk", ...) for fewer than 2 waypoints, no walkable pair, a bad
// parameter (naming the field), with in_order for a leg that is not walkable (naming it), and for
// a mesh without a triangle of non-zero area, spanning more than 1e7 m, or whose triangles overlap
// more than 2^27 grid cells, or a via grid of more than 4M columns.
Trace level_walk(const Mesh& mesh, const std::vector<glm::dvec3>& waypoints_world, const LevelWalkParams& p,
                 LevelWalkStats* stats = nullptr);

// "x y z" per line, world metres; '#' starts a comment; blank lines skipped. InputError("path:line").
std::vector<glm::dvec3> read_waypoints(const std::string& path);

}  // namespace vtsim
