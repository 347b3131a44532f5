#include "sim/view/level_walk.h"

#include <fmt/core.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <queue>
#include <string>
#include <vector>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

#include "core/error.h"
#include "core/input_file.h"
#include "sim/view/render_util.h"
#include "sim/trace/trace_io.h"
#include "sim/trace/trace_resample.h"
#include "sim/trace/trace_transform.h"

namespace vtsim {

namespace {

// Raycasts against a triangle soup through a uniform grid (Amanatides & Woo 1987, "A Fast Voxel
// Traversal Algorithm for Ray Tracing"), triangles tested with Moeller & Trumbore 1997. Each
// triangle is listed in every cell its bounding box overlaps. Build O(T + sum of cells per
// triangle); a query visits the cells the ray crosses (O(cells along the ray + triangles in them))
// and stops at the first cell holding a hit nearer than the cell's exit. About 2 cells per
// triangle, at most 256 per axis and 4M in all. Immutable after construction but for a ray
// counter: one thread.
class LwGrid {
 public:
  explicit LwGrid(const Mesh& m) {
    tris_.reserve(m.tris.size());
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    for (const Mesh::Tri& t : m.tris) {
      const glm::dvec3 a = m.positions[t.p[0]], b = m.positions[t.p[1]], c = m.positions[t.p[2]];
      const glm::dvec3 n = glm::cross(b - a, c - a);
      const double len = glm::length(n);
      if (!(len > 0.0) || !std::isfinite(len)) continue;  // zero area: no ray can hit it
      tris_.push_back({a, b - a, c - a, std::abs(n.z) / len});
      lo = glm::min(lo, glm::min(a, glm::min(b, c)));
      hi = glm::max(hi, glm::max(a, glm::max(b, c)));
    }
    if (tris_.empty()) throw InputError("level_walk", "the mesh has no triangle of non-zero area");
    if (!(std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z}) <= 1e7))
      throw InputError("level_walk", "the mesh spans more than 10,000 km: not a level in metres (see --unit-m)");
    // Pad: a flat level (all z equal) still has cells of non-zero height.
    const double pad = std::max(1e-3, 1e-6 * std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z}));
    lo_ = lo - pad;
    const glm::dvec3 ext = hi + pad - lo_;
    double h = std::cbrt(ext.x * ext.y * ext.z / (2.0 * static_cast<double>(tris_.size())));
    for (;;) {
      std::uint64_t cells = 1;
      for (int k = 0; k < 3; ++k) {
        n_[k] = static_cast<int>(std::clamp(std::ceil(ext[k] / h), 1.0, 256.0));
        cells *= static_cast<std::uint64_t>(n_[k]);
      }
      if (cells <= (std::uint64_t{1} << 22)) break;
      h *= 1.25;
    }
    for (int k = 0; k < 3; ++k) cell_[k] = ext[k] / n_[k];
    const std::size_t cells = static_cast<std::size_t>(n_[0]) * static_cast<std::size_t>(n_[1]) *
                              static_cast<std::size_t>(n_[2]);
    std::uint64_t listed = 0;  // triangle-cell pairs, checked before anything is allocated for them
    for (const Tri& t : tris_) {
      const glm::dvec3 b = t.a + t.e1, c = t.a + t.e2;
      const glm::ivec3 c0 = cell_of(glm::min(t.a, glm::min(b, c))), c1 = cell_of(glm::max(t.a, glm::max(b, c)));
      listed += static_cast<std::uint64_t>(c1.x - c0.x + 1) * static_cast<std::uint64_t>(c1.y - c0.y + 1) *
                static_cast<std::uint64_t>(c1.z - c0.z + 1);
    }
    if (listed > (std::uint64_t{1} << 27))  // 512 MiB of indices
      throw InputError("level_walk", fmt::format("the mesh's {} triangles overlap {} grid cells (limit 2^27): many "
                                                 "large triangles crossing the level", tris_.size(), listed));
    start_.assign(cells + 1, 0);
    for (int pass = 0; pass < 2; ++pass) {
      std::vector<std::uint32_t> fill;
      if (pass == 1) {
        for (std::size_t c = 0; c < cells; ++c) start_[c + 1] += start_[c];
        items_.resize(start_[cells]);
        fill.assign(start_.begin(), start_.end() - 1);
      }
      for (std::size_t i = 0; i < tris_.size(); ++i) {
        const Tri& t = tris_[i];
        const glm::dvec3 b = t.a + t.e1, c = t.a + t.e2;
        const glm::ivec3 c0 = cell_of(glm::min(t.a, glm::min(b, c))), c1 = cell_of(glm::max(t.a, glm::max(b, c)));
        for (int z = c0.z; z <= c1.z; ++z)
          for (int y = c0.y; y <= c1.y; ++y)
            for (int x = c0.x; x <= c1.x; ++x) {
              const std::size_t id = index(x, y, z);
              if (pass == 0) ++start_[id + 1];
              else items_[fill[id]++] = static_cast<std::uint32_t>(i);
            }
      }
    }
  }

  std::size_t cells() const { return start_.size() - 1; }
  glm::dvec3 lo() const { return lo_; }
  glm::dvec3 hi() const { return lo_ + cell_ * glm::dvec3(n_[0], n_[1], n_[2]); }

  // Nearest hit of o + t d for t in [1e-9, tmax] (d need not be unit): true with t and the
  // hit triangle's |unit normal z|.
  bool hit(const glm::dvec3& o, const glm::dvec3& d, double tmax, double& t_hit, double& nz) const {
    ++rays_;
    double t0 = 0.0, t1 = tmax;
    if (!detail::clip_ray_to_box(o, d, lo_, hi(), t0, t1)) return false;  // clip to the grid box
    glm::ivec3 c = cell_of(o + d * t0), step(0);
    glm::dvec3 t_next(std::numeric_limits<double>::infinity()), t_delta(std::numeric_limits<double>::infinity());
    for (int k = 0; k < 3; ++k) {
      if (d[k] == 0.0) continue;
      step[k] = d[k] > 0 ? 1 : -1;
      const double edge = lo_[k] + cell_[k] * (c[k] + (d[k] > 0 ? 1 : 0));
      t_next[k] = (edge - o[k]) / d[k];
      t_delta[k] = cell_[k] / std::abs(d[k]);
    }
    double best = std::numeric_limits<double>::infinity();
    for (;;) {
      const std::size_t id = index(c.x, c.y, c.z);
      for (std::uint32_t k = start_[id]; k < start_[id + 1]; ++k) {
        double t = 0.0;
        if (intersect(tris_[items_[k]], o, d, t) && t <= tmax && t < best) {
          best = t;
          nz = tris_[items_[k]].nz;
        }
      }
      const int axis = t_next.x < t_next.y ? (t_next.x < t_next.z ? 0 : 2) : (t_next.y < t_next.z ? 1 : 2);
      const double exit = t_next[axis];
      if (best <= exit || exit > t1) break;
      c[axis] += step[axis];
      if (c[axis] < 0 || c[axis] >= n_[axis]) break;
      t_next[axis] += t_delta[axis];
    }
    if (!(best <= tmax)) return false;
    t_hit = best;
    return true;
  }

  std::size_t rays() const { return rays_; }

 private:
  struct Tri {
    glm::dvec3 a, e1, e2;
    double nz;  // |z| of the unit normal
  };

  static bool intersect(const Tri& tr, const glm::dvec3& o, const glm::dvec3& d, double& t) {
    const glm::dvec3 pv = glm::cross(d, tr.e2);
    const double det = glm::dot(tr.e1, pv);
    if (det == 0.0) return false;  // parallel to the plane
    const double inv = 1.0 / det;
    const glm::dvec3 tv = o - tr.a;
    const double u = glm::dot(tv, pv) * inv;
    if (u < 0.0 || u > 1.0) return false;
    const glm::dvec3 qv = glm::cross(tv, tr.e1);
    const double v = glm::dot(d, qv) * inv;
    if (v < 0.0 || u + v > 1.0) return false;
    t = glm::dot(tr.e2, qv) * inv;
    return t >= 1e-9;
  }

  glm::ivec3 cell_of(const glm::dvec3& p) const {
    glm::ivec3 c;
    for (int k = 0; k < 3; ++k) {
      const double f = std::floor((p[k] - lo_[k]) / cell_[k]);
      c[k] = static_cast<int>(std::clamp(f, 0.0, static_cast<double>(n_[k] - 1)));
    }
    return c;
  }
  std::size_t index(int x, int y, int z) const {
    return (static_cast<std::size_t>(z) * static_cast<std::size_t>(n_[1]) + static_cast<std::size_t>(y)) *
               static_cast<std::size_t>(n_[0]) +
           static_cast<std::size_t>(x);
  }

  std::vector<Tri> tris_;
  glm::dvec3 lo_{0.0}, cell_{1.0};
  int n_[3] = {1, 1, 1};
  std::vector<std::uint32_t> start_, items_;
  mutable std::size_t rays_ = 0;
};

// A walkable straight leg: floor heights at n + 1 evenly spaced points from a to b.
struct LwLeg {
  glm::dvec2 a, b;
  std::vector<double> floor;  // floor z at lerp(a, b, k / n)
  double length_m = 0.0;      // 3-D, along the samples
};

struct LwWalker {
  const LwGrid& grid;
  const LevelWalkParams& p;

  // The first surface below `top` within `depth`, if it is a floor (not too steep).
  bool floor_below(glm::dvec2 xy, double top, double depth, double& z) const {
    double t = 0.0, nz = 0.0;
    if (!grid.hit({xy, top}, {0.0, 0.0, -1.0}, depth, t, nz) || nz < p.min_floor_nz) return false;
    z = top - t;
    return true;
  }
  bool clear(const glm::dvec3& a, const glm::dvec3& b) const {
    double t = 0.0, nz = 0.0;
    return !grid.hit(a, b - a, 1.0, t, nz);
  }

  // The leg from floor point (a, fa) toward b (floor fb), or an empty floor list with `why` set.
  // `refused` counts the reasons: sight, floor, headroom, blocked, other level.
  LwLeg leg(glm::dvec2 a, double fa, glm::dvec2 b, double fb, std::string* why, std::size_t* refused = nullptr) const {
    LwLeg out{a, b, {}, 0.0};
    const double dist = glm::length(b - a);
    const auto fail = [&](int reason, glm::dvec2 at, double z) {
      static const char* const names[] = {"no line of sight at eye height", "no floor within the step limit",
                                           "no headroom", "blocked", "the floor ends at another level"};
      if (refused) ++refused[reason];
      if (why) *why = fmt::format("{} at ({:.3f}, {:.3f}, {:.3f}) m", names[reason], at.x, at.y, z);
      out.floor.clear();
      return out;
    };
    if (!clear({a, fa + p.eye_m}, {b, fb + p.eye_m})) return fail(0, a, fa + p.eye_m);
    const int n = std::max(1, static_cast<int>(std::ceil(dist / p.sample_m)));
    const glm::dvec2 side = dist > 0 ? glm::dvec2(-(b - a).y, (b - a).x) * (p.radius_m / dist) : glm::dvec2(0.0);
    const double knee = p.max_step_m + 0.05;  // just above a step the walker climbs
    out.floor.reserve(static_cast<std::size_t>(n) + 1);
    out.floor.push_back(fa);
    for (int k = 1; k <= n; ++k) {
      const glm::dvec2 q0 = a + (b - a) * (static_cast<double>(k - 1) / n), q = a + (b - a) * (static_cast<double>(k) / n);
      const double f0 = out.floor.back();
      double f = 0.0;
      if (!floor_below(q, f0 + p.max_step_m, 2.0 * p.max_step_m + 1e-3, f))
        return fail(1, q, f0);
      if (!clear({q, f + 0.05}, {q, f + p.eye_m + 0.1})) return fail(2, q, f);
      for (const double h : {knee, p.eye_m})
        for (const double s : {0.0, 1.0, -1.0})
          if (!clear({q0 + side * s, f0 + h}, {q + side * s, f + h})) return fail(3, q, f + h);
      out.floor.push_back(f);
      out.length_m += glm::length(glm::dvec3(q - q0, f - f0));
    }
    if (std::abs(out.floor.back() - fb) > p.max_step_m) return fail(4, b, out.floor.back());
    return out;
  }
};

void lw_need(bool ok, const char* field, double v, const char* rule) {
  if (!ok) throw InputError("level_walk", fmt::format("{} = {} {}", field, v, rule));
}

void lw_validate(const LevelWalkParams& p) {
  const auto in = [](double v, double lo, double hi) { return std::isfinite(v) && v > lo && v <= hi; };
  lw_need(in(p.speed_mps, 0, 100), "speed_mps", p.speed_mps, "is not in (0, 100]");
  lw_need(in(p.fps, 0, 1000), "fps", p.fps, "is not in (0, 1000]");
  lw_need(in(p.eye_m, 0, 100), "eye_m", p.eye_m, "is not in (0, 100]");
  lw_need(std::isfinite(p.pitch_deg) && std::abs(p.pitch_deg) <= 90, "pitch_deg", p.pitch_deg, "is not in [-90, 90]");
  lw_need(p.vfov_deg >= kMinVfov_deg && p.vfov_deg <= kMaxVfov_deg, "vfov_deg", p.vfov_deg, "is not in [0.01, 179]");
  lw_need(p.image_width >= 1 && p.image_width <= kMaxImageSide, "image_width", p.image_width, "is out of range");
  lw_need(p.image_height >= 1 && p.image_height <= kMaxImageSide, "image_height", p.image_height, "is out of range");
  lw_need(std::isfinite(p.duration_s) && p.duration_s >= 0 && p.duration_s <= 1e6, "duration_s", p.duration_s,
          "is not in [0, 1e6]");
  lw_need(in(p.max_step_m, 0, 100), "max_step_m", p.max_step_m, "is not in (0, 100]");
  lw_need(std::isfinite(p.min_floor_nz) && p.min_floor_nz >= 0 && p.min_floor_nz <= 1, "min_floor_nz", p.min_floor_nz,
          "is not in [0, 1]");
  lw_need(in(p.sample_m, 0.001, 100), "sample_m", p.sample_m, "is not in (0.001, 100]");
  lw_need(std::isfinite(p.radius_m) && p.radius_m >= 0 && p.radius_m <= 100, "radius_m", p.radius_m, "is not in [0, 100]");
  lw_need(in(p.max_leg_m, 0, 1e5), "max_leg_m", p.max_leg_m, "is not in (0, 1e5]");
  lw_need(p.max_leg_m / p.sample_m <= 1e6, "max_leg_m", p.max_leg_m, "is more than 1e6 samples (see sample_m)");
  lw_need(in(p.probe_m, 0, 1e4), "probe_m", p.probe_m, "is not in (0, 1e4]");
  lw_need(std::isfinite(p.smooth_m) && p.smooth_m >= 0 && p.smooth_m <= 1e3, "smooth_m", p.smooth_m, "is not in [0, 1000]");
  lw_need(std::isfinite(p.via_grid_m) && (p.via_grid_m == 0 || (p.via_grid_m >= 0.25 && p.via_grid_m <= 1e3)),
          "via_grid_m", p.via_grid_m, "is not 0 or in [0.25, 1000]");
  lw_need(in(p.max_turn_dps, 0, 1e5), "max_turn_dps", p.max_turn_dps, "is not in (0, 1e5]");
  lw_need(std::isfinite(p.look_ahead_m) && p.look_ahead_m >= 0 && p.look_ahead_m <= 1e3, "look_ahead_m",
          p.look_ahead_m, "is not in [0, 1000]");
}

// The walked path: horizontal points with their floor, cumulative horizontal length, and the
// integral of the floor over it (for the box-filtered eye height).
struct LwPath {
  std::vector<glm::dvec2> xy;
  std::vector<double> floor, s, integral;

  void add(glm::dvec2 q, double f) {
    if (!xy.empty() && q == xy.back()) {  // a zero-length step (a waypoint on the previous one)
      floor.back() = f;
      return;
    }
    const double ds = xy.empty() ? 0.0 : glm::length(q - xy.back());
    integral.push_back(xy.empty() ? 0.0 : integral.back() + ds * (floor.back() + f) * 0.5);
    s.push_back(xy.empty() ? 0.0 : s.back() + ds);
    xy.push_back(q);
    floor.push_back(f);
  }
  double length() const { return s.back(); }
  // Segment k with s[k] <= x <= s[k + 1] (x clamped to [0, length]).
  std::size_t seg(double x) const {
    if (xy.size() < 2) return 0;
    const auto it = std::upper_bound(s.begin(), s.end(), x);
    const std::size_t k = it == s.begin() ? 0 : static_cast<std::size_t>(it - s.begin()) - 1;
    return std::min(k, xy.size() - 2);
  }
  glm::dvec2 at(double x) const {
    x = std::clamp(x, 0.0, length());
    if (xy.size() < 2) return xy[0];
    const std::size_t k = seg(x);
    const double u = (x - s[k]) / (s[k + 1] - s[k]);
    return xy[k] + (xy[k + 1] - xy[k]) * u;
  }
  double floor_at(double x) const {
    if (xy.size() < 2) return floor[0];
    const std::size_t k = seg(std::clamp(x, 0.0, length()));
    const double u = std::clamp((x - s[k]) / (s[k + 1] - s[k]), 0.0, 1.0);
    return floor[k] + (floor[k + 1] - floor[k]) * u;
  }
  // Integral of the floor from 0 to x; the floor is held constant beyond the ends.
  double floor_integral(double x) const {
    if (x <= 0.0) return x * floor[0];
    if (xy.size() < 2 || x >= length()) return integral.back() + (x - length()) * floor.back();
    const std::size_t k = seg(x);
    const double dx = x - s[k];
    return integral[k] + dx * (floor[k] + floor_at(x)) * 0.5;
  }
  double smoothed_floor(double x, double w) const {
    if (w <= 0.0) return floor_at(x);
    return (floor_integral(x + w * 0.5) - floor_integral(x - w * 0.5)) / w;
  }
};

double lw_wrap180(double a) {
  a = std::fmod(a, 360.0);
  if (a > 180.0) a -= 360.0;
  if (a <= -180.0) a += 360.0;
  return a;
}

// What level_walk's steps share: the mesh's grid and walker, the parameters, the waypoints and the
// floor found below each (has_floor: one was).
struct LwGraph;
struct LwInput {
  const LwGrid& grid;
  const LwWalker& walker;
  const LevelWalkParams& p;
  const std::vector<glm::dvec3>& wp;
  std::vector<double> floor;
  std::vector<char> has_floor;
  std::size_t n = wp.size();

  glm::dvec2 xy(std::size_t i) const { return {wp[i].x, wp[i].y}; }
  void walk_in_order(LevelWalkStats& st, LwPath& path, std::vector<std::size_t>& order) const;
  LwGraph graph(LevelWalkStats& st) const;
  void tour(const LwGraph& g, LevelWalkStats& st, LwPath& path, std::vector<std::size_t>& order) const;
};

// in_order: the waypoints in the order given, each leg walkable straight, or an InputError.
void LwInput::walk_in_order(LevelWalkStats& st, LwPath& path, std::vector<std::size_t>& order) const {
  for (std::size_t i = 0; i < n; ++i)
    if (!has_floor[i])
      throw InputError("level_walk", fmt::format("waypoint {} ({}, {}, {}): no floor within {} m below it", i + 1,
                                                 wp[i].x, wp[i].y, wp[i].z, p.probe_m));
  path.add(xy(0), floor[0]);
  order.push_back(0);
  for (std::size_t i = 0; i + 1 < n; ++i) {
    std::string why;
    const LwLeg leg = walker.leg(xy(i), floor[i], xy(i + 1), floor[i + 1], &why);
    if (leg.floor.empty())
      throw InputError("level_walk", fmt::format("waypoint {} -> {}: not walkable straight: {}", i + 1, i + 2, why));
    ++st.legs;
    const std::size_t m = leg.floor.size() - 1;
    for (std::size_t k = 1; k <= m; ++k)
      path.add(leg.a + (leg.b - leg.a) * (static_cast<double>(k) / static_cast<double>(m)), leg.floor[k]);
    st.path_length_m += leg.length_m;
    order.push_back(i + 1);
  }
}

// The graph level_walk tours otherwise: nodes (positions, floors) and edges weighted by length.
struct LwGraph {
  std::vector<glm::dvec2> nxy;
  std::vector<double> nfloor;
  std::vector<std::vector<std::pair<std::size_t, double>>> adj;
};

LwGraph LwInput::graph(LevelWalkStats& st) const {
  LwGraph g;
  std::vector<glm::dvec2>& nxy = g.nxy;
  std::vector<double>& nfloor = g.nfloor;
  // The graph's nodes: the waypoints with a floor (0 .. n-1), then with via_grid_m > 0 via
  // points: every floor with headroom found on a grid of columns via_grid_m apart (each column
  // cast down from the top of the mesh, floor after floor, at most 16).
  for (std::size_t i = 0; i < n; ++i) {
    nxy.push_back(xy(i));
    nfloor.push_back(floor[i]);
  }
  std::vector<std::vector<std::size_t>> columns;
  int cols_x = 0, cols_y = 0;
  if (p.via_grid_m > 0.0) {
    const glm::dvec3 lo = grid.lo(), hi = grid.hi();
    cols_x = static_cast<int>(std::min(1e7, std::floor((hi.x - lo.x) / p.via_grid_m) + 1));
    cols_y = static_cast<int>(std::min(1e7, std::floor((hi.y - lo.y) / p.via_grid_m) + 1));
    if (static_cast<double>(cols_x) * cols_y > 4e6)
      throw InputError("level_walk", fmt::format("via_grid_m = {} gives {} x {} columns over the mesh (limit 4M): "
                                                 "raise it", p.via_grid_m, cols_x, cols_y));
    columns.resize(static_cast<std::size_t>(cols_x) * static_cast<std::size_t>(cols_y));
    for (int iy = 0; iy < cols_y; ++iy)
      for (int ix = 0; ix < cols_x; ++ix) {
        const glm::dvec2 q(lo.x + (ix + 0.5) * p.via_grid_m, lo.y + (iy + 0.5) * p.via_grid_m);
        double top = hi.z + 1.0;
        for (int k = 0; k < 16; ++k) {
          double t = 0.0, nz = 0.0;
          if (!grid.hit({q, top}, {0.0, 0.0, -1.0}, top - lo.z + 1.0, t, nz)) break;
          const double f = top - t;
          top = f - 0.01;
          if (nz < p.min_floor_nz || !walker.clear({q, f + 0.05}, {q, f + p.eye_m + 0.1})) continue;
          columns[static_cast<std::size_t>(iy) * static_cast<std::size_t>(cols_x) + static_cast<std::size_t>(ix)]
              .push_back(nxy.size());
          nxy.push_back(q);
          nfloor.push_back(f);
        }
      }
  }
  const std::size_t nn = nxy.size();
  st.via_points = nn - n;
  // Edges: waypoint pairs within max_leg_m; via points to those of the 8 neighbouring columns;
  // waypoints to the via points of the columns within 2 cells. Each a walkable straight leg;
  // weight: its 3-D length.
  g.adj.resize(nn);
  std::vector<std::vector<std::pair<std::size_t, double>>>& adj = g.adj;
  const auto try_edge = [&](std::size_t i, std::size_t j) {
    if (glm::length(nxy[j] - nxy[i]) > p.max_leg_m) return;
    const LwLeg leg = walker.leg(nxy[i], nfloor[i], nxy[j], nfloor[j], nullptr, i < n && j < n ? st.refused : nullptr);
    if (leg.floor.empty()) return;
    adj[i].push_back({j, leg.length_m});
    adj[j].push_back({i, leg.length_m});
    ++st.legs;
  };
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j)
      if (has_floor[i] && has_floor[j]) try_edge(i, j);
  const auto column = [&](int ix, int iy) -> const std::vector<std::size_t>* {
    if (ix < 0 || iy < 0 || ix >= cols_x || iy >= cols_y) return nullptr;
    return &columns[static_cast<std::size_t>(iy) * static_cast<std::size_t>(cols_x) + static_cast<std::size_t>(ix)];
  };
  for (int iy = 0; iy < cols_y; ++iy)
    for (int ix = 0; ix < cols_x; ++ix)
      for (const std::size_t u : *column(ix, iy))
        for (const auto& [dx, dy] : {std::pair{1, 0}, std::pair{0, 1}, std::pair{1, 1}, std::pair{1, -1}})
          if (const auto* c = column(ix + dx, iy + dy))
            for (const std::size_t v : *c) try_edge(u, v);
  if (p.via_grid_m > 0.0)
    for (std::size_t i = 0; i < n; ++i) {
      if (!has_floor[i]) continue;
      const glm::dvec3 lo = grid.lo();
      const int cx = static_cast<int>(std::floor((nxy[i].x - lo.x) / p.via_grid_m));
      const int cy = static_cast<int>(std::floor((nxy[i].y - lo.y) / p.via_grid_m));
      for (int dy = -2; dy <= 2; ++dy)
        for (int dx = -2; dx <= 2; ++dx)
          if (const auto* c = column(cx + dx, cy + dy))
            for (const std::size_t v : *c) try_edge(i, v);
    }
  return g;
}

// The tour of the graph: from the start (below), each next the nearest unvisited waypoint by
// Dijkstra, the chain between them string-pulled into straight legs; `order` the waypoints visited.
void LwInput::tour(const LwGraph& g, LevelWalkStats& st, LwPath& path, std::vector<std::size_t>& order) const {
  const std::vector<glm::dvec2>& nxy = g.nxy;
  const std::vector<double>& nfloor = g.nfloor;
  const std::vector<std::vector<std::pair<std::size_t, double>>>& adj = g.adj;
  const std::size_t nn = nxy.size();
  // Start in the part of the graph holding the most waypoints (ties: the one holding the lowest
  // index), at its lowest waypoint: with spawn points listed first, the first spawn point there.
  std::vector<std::size_t> part(nn, nn), part_wp;
  for (std::size_t i = 0; i < n; ++i) {
    if (part[i] != nn || adj[i].empty()) continue;
    part[i] = part_wp.size();
    std::size_t count = 0;
    std::vector<std::size_t> stack = {i};
    while (!stack.empty()) {
      const std::size_t u = stack.back();
      stack.pop_back();
      count += u < n ? 1 : 0;
      for (const auto& [v, w] : adj[u])
        if (part[v] == nn) {
          part[v] = part[i];
          stack.push_back(v);
        }
    }
    part_wp.push_back(count);
  }
  std::size_t start = n;
  for (std::size_t i = 0; i < n; ++i)
    if (part[i] != nn && part_wp[part[i]] >= 2 && (start == n || part_wp[part[i]] > part_wp[part[start]])) start = i;
  if (start == n)
    throw InputError("level_walk", fmt::format("no two of the {} waypoints ({} with a floor) are joined by walkable "
                                               "straight legs (line of sight at eye height {} m, floor steps <= {} m, "
                                               "at most {} m apart{})",
                                               n, n - st.no_floor, p.eye_m, p.max_step_m, p.max_leg_m,
                                               p.via_grid_m > 0 ? ", or through via points" : ""));
  std::vector<char> visited(n, 0);
  visited[start] = 1;
  order.push_back(start);
  path.add(xy(start), floor[start]);
  std::size_t cur = start;
  for (;;) {
    // Dijkstra from cur with a binary heap, O(E log V); ties broken by node index (deterministic).
    std::vector<double> dist(nn, std::numeric_limits<double>::infinity());
    std::vector<std::size_t> prev(nn, nn);
    std::priority_queue<std::pair<double, std::size_t>, std::vector<std::pair<double, std::size_t>>, std::greater<>> heap;
    dist[cur] = 0.0;
    heap.push({0.0, cur});
    while (!heap.empty()) {
      const auto [d, u] = heap.top();
      heap.pop();
      if (d > dist[u]) continue;
      for (const auto& [v, w] : adj[u])
        if (d + w < dist[v]) {
          dist[v] = d + w;
          prev[v] = u;
          heap.push({dist[v], v});
        }
    }
    std::size_t target = n;
    for (std::size_t i = 0; i < n; ++i)
      if (!visited[i] && std::isfinite(dist[i]) && (target == n || dist[i] < dist[target])) target = i;
    if (target == n) break;
    std::vector<std::size_t> chain;
    for (std::size_t v = target; v != cur; v = prev[v]) chain.push_back(v);
    chain.push_back(cur);
    std::reverse(chain.begin(), chain.end());
    // String pulling: from each node, the furthest node of the chain (at most 16 ahead) that a
    // straight leg reaches, so that a path through via points does not zig-zag along the grid.
    for (std::size_t i = 0; i + 1 < chain.size();) {
      std::size_t j = std::min(chain.size() - 1, i + 16);
      LwLeg leg;
      for (;; --j) {
        const std::size_t u = chain[i], v = chain[j];
        leg = walker.leg(nxy[u], nfloor[u], nxy[v], nfloor[v], nullptr);
        if (!leg.floor.empty() || j == i + 1) break;
      }
      if (leg.floor.empty()) {  // cannot happen: chain[i] - chain[i+1] is an edge; stay safe
        const std::size_t u = chain[i], v = chain[i + 1];
        leg = walker.leg(nxy[u], nfloor[u], nxy[v], nfloor[v], nullptr);
      }
      const std::size_t m = leg.floor.size() - 1;
      for (std::size_t k = 1; k <= m; ++k)
        path.add(leg.a + (leg.b - leg.a) * (static_cast<double>(k) / static_cast<double>(m)), leg.floor[k]);
      st.path_length_m += leg.length_m;
      for (std::size_t k = i + 1; k <= j; ++k)
        if (chain[k] < n && !visited[chain[k]]) {
          visited[chain[k]] = 1;
          order.push_back(chain[k]);
        }
      i = j;
    }
    cur = target;
  }
  for (std::size_t i = 0; i < n; ++i)
    if (has_floor[i] && !visited[i]) st.unreachable_list.push_back(i);
  st.unreachable = st.unreachable_list.size();
}

// The walk's poses: back and forth along the path at speed_mps, the view turning towards the path
// ahead at most max_turn_dps.
Trace lw_poses(const LwPath& path, const std::vector<std::size_t>& order, const LevelWalkParams& p, std::size_t n,
               LevelWalkStats& st) {
  st.visited = order.size();
  st.order = order;
  const double length = path.length();
  st.tour_s = length / p.speed_mps;
  const double duration = p.duration_s > 0.0 ? p.duration_s : st.tour_s;
  lw_need(duration * p.fps + 1.0 <= static_cast<double>(kMaxTraceFrames), "duration_s", duration,
          "at this fps gives too many frames");

  Trace trace;
  trace.image_width = p.image_width;
  trace.image_height = p.image_height;
  trace.name = fmt::format("level_walk waypoints={} visited={} speed_mps={} eye_m={} fps={} pitch_deg={} vfov_deg={}{}",
                           n, st.visited, p.speed_mps, p.eye_m, p.fps, p.pitch_deg, p.vfov_deg,
                           p.in_order ? " in_order" : "");
  const auto last = static_cast<std::int64_t>(std::floor(duration * p.fps + 1e-6));
  trace.poses.reserve(static_cast<std::size_t>(last + 1));
  // Arc length at time t: back and forth along the path when the duration outlasts one pass.
  const auto arc = [&](double t) {
    if (length <= 0.0) return 0.0;
    const double x = std::fmod(p.speed_mps * t, 2.0 * length);
    return x <= length ? x : 2.0 * length - x;
  };
  const auto dir = [&](double t) {  // +1 forward, -1 on the way back
    if (length <= 0.0) return 1.0;
    return std::fmod(p.speed_mps * t, 2.0 * length) <= length ? 1.0 : -1.0;
  };
  const auto target_yaw = [&](double s, double sign, double fallback) {
    const glm::dvec2 d = path.at(s + sign * std::max(p.look_ahead_m, 1e-3)) - path.at(s);
    if (glm::length(d) < 1e-9) return fallback;
    return std::atan2(d.y, d.x) * (180.0 / std::numbers::pi);
  };
  double yaw = 0.0;
  for (std::int64_t i = 0; i <= last; ++i) {
    Pose pose;
    pose.t_s = static_cast<double>(i) / p.fps;
    pose.vfov_deg = p.vfov_deg;
    const double s = arc(pose.t_s);
    const glm::dvec2 q = path.at(s);
    pose.pos_m = glm::dvec3(q, path.smoothed_floor(s, p.smooth_m) + p.eye_m);
    const double want = target_yaw(s, dir(pose.t_s), yaw);
    if (i == 0) yaw = want;
    else {
      const double step = p.max_turn_dps / p.fps;
      yaw = lw_wrap180(yaw + std::clamp(lw_wrap180(want - yaw), -step, step));
    }
    pose.q = yaw_pitch_quat(yaw, p.pitch_deg);
    trace.poses.push_back(pose);
  }
  return trace;
}

}  // namespace

Trace level_walk(const Mesh& mesh, const std::vector<glm::dvec3>& wp, const LevelWalkParams& p, LevelWalkStats* stats) {
  lw_validate(p);
  if (wp.size() < 2)
    throw InputError("level_walk", fmt::format("{} waypoint(s): a walk needs at least 2", wp.size()));
  for (std::size_t i = 0; i < wp.size(); ++i)
    if (!std::isfinite(wp[i].x) || !std::isfinite(wp[i].y) || !std::isfinite(wp[i].z))
      throw InputError("level_walk", fmt::format("waypoint {} is not finite", i + 1));
  const LwGrid grid(mesh);
  const LwWalker walker{grid, p};
  LevelWalkStats st;
  st.waypoints = wp.size();
  st.grid_cells = grid.cells();
  const std::size_t n = wp.size();
  LwInput in{grid, walker, p, wp, std::vector<double>(n, 0.0), std::vector<char>(n, 0), n};
  for (std::size_t i = 0; i < n; ++i) {
    in.has_floor[i] = walker.floor_below({wp[i].x, wp[i].y}, wp[i].z + 0.1, p.probe_m + 0.1, in.floor[i]);
    if (!in.has_floor[i]) st.no_floor_list.push_back(i);
  }
  st.no_floor = st.no_floor_list.size();

  LwPath path;
  std::vector<std::size_t> order;
  if (p.in_order) in.walk_in_order(st, path, order);
  else in.tour(in.graph(st), st, path, order);
  Trace trace = lw_poses(path, order, p, n, st);
  st.rays = grid.rays();
  validate_trace(trace, "level_walk");
  if (stats) *stats = std::move(st);
  return trace;
}

std::vector<glm::dvec3> read_waypoints(const std::string& path) {
  const std::string text = read_regular_file(path, std::uint64_t{64} << 20, "not a waypoint list");
  std::vector<glm::dvec3> out;
  std::size_t b = 0;
  long long line = 0;
  while (b < text.size()) {
    std::size_t e = text.find('\n', b);
    if (e == std::string::npos) e = text.size();
    std::string_view l(text.data() + b, e - b);
    b = e + 1;
    ++line;
    if (const std::size_t h = l.find('#'); h != std::string_view::npos) l = l.substr(0, h);
    double v[3] = {0, 0, 0};
    int k = 0;
    std::size_t i = 0;
    for (;;) {
      while (i < l.size() && (l[i] == ' ' || l[i] == '\t' || l[i] == '\r' || l[i] == ',')) ++i;
      if (i >= l.size()) break;
      std::size_t j = i;
      while (j < l.size() && l[j] != ' ' && l[j] != '\t' && l[j] != '\r' && l[j] != ',') ++j;
      double x = 0.0;
      const auto [ptr, ec] = std::from_chars(l.data() + i, l.data() + j, x);
      if (k == 3 || ec != std::errc() || ptr != l.data() + j || !std::isfinite(x))
        throw InputError(at_line(path, line), fmt::format("'{}' is not three finite numbers x y z (metres)", l));
      v[k++] = x;
      i = j;
    }
    if (k == 0) continue;
    if (k != 3) throw InputError(at_line(path, line), fmt::format("'{}' is not three numbers x y z (metres)", l));
    out.push_back({v[0], v[1], v[2]});
  }
  return out;
}

}  // namespace vtsim
