#include "sim/sweep/tune.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "core/error.h"
#include "sim/run/real_replay.h"
#include "sim/run/replay.h"
#include "sim/view/scene.h"
#include "stream/store/tile_store.h"

namespace vtsim {

namespace {

// The grid as index vectors: point index = sum of idx[a] * stride[a], the first axis slowest.
struct Grid {
  std::vector<int> n, stride;
  std::vector<bool> cost;  // per axis
  int points = 1;
  std::vector<int> idx(int p) const {
    std::vector<int> v(n.size());
    for (std::size_t a = 0; a < n.size(); ++a) v[a] = (p / stride[a]) % n[a];
    return v;
  }
  int point(const std::vector<int>& v) const {
    int p = 0;
    for (std::size_t a = 0; a < n.size(); ++a) p += v[a] * stride[a];
    return p;
  }
  // a <= b: equal on every other axis, no dearer on any cost axis.
  bool le(int a, int b) const {
    const auto va = idx(a), vb = idx(b);
    for (std::size_t k = 0; k < n.size(); ++k)
      if (cost[k] ? va[k] > vb[k] : va[k] != vb[k]) return false;
    return true;
  }
  std::vector<int> minimal(const std::set<int>& s) const {
    std::vector<int> out;
    for (int p : s)
      if (std::none_of(s.begin(), s.end(), [&](int q) { return q != p && le(q, p); })) out.push_back(p);
    return out;
  }
};

Grid make_grid(const SweepSpec& spec) {
  Grid g;
  for (const SweepAxis& axis : spec.grid) {
    g.n.push_back(static_cast<int>(axis.values.size()));
    g.cost.push_back(std::find(spec.tune.costs.begin(), spec.tune.costs.end(), axis.key) != spec.tune.costs.end());
  }
  for (auto it = g.n.rbegin(); it != g.n.rend(); ++it) {  // the last axis fastest
    g.stride.push_back(g.points);
    g.points *= *it;
  }
  std::reverse(g.stride.begin(), g.stride.end());
  return g;
}

}  // namespace

TuneVerdict judge(const TuneSpec& tune, const std::vector<nlohmann::json>& rows) {
  TuneVerdict v;
  v.pass = true;
  v.worst.assign(tune.constraints.size(), std::numeric_limits<double>::quiet_NaN());
  for (const nlohmann::json& r : rows) {
    if (r.value("status", std::string()) != "ok") {
      v.pass = false;
      if (v.failure.empty()) v.failure = "a replay failed: " + r.value("error", std::string("?"));
      continue;
    }
    for (std::size_t c = 0; c < tune.constraints.size(); ++c) {
      const TuneConstraint& k = tune.constraints[c];
      const nlohmann::json* x = summary_path(r["summary"], k.metric);
      if (!x || !x->is_number()) {
        v.pass = false;
        if (v.failure.empty()) v.failure = "no metric '" + k.metric + "' in the summary";
        continue;
      }
      const double val = x->get<double>();
      if (std::isnan(v.worst[c]) || (k.at_most ? val > v.worst[c] : val < v.worst[c])) v.worst[c] = val;
      if (k.at_most ? !(val <= k.bound) : !(val >= k.bound)) {
        if (v.failure.empty()) v.failure = fmt::format("{} = {:.6g} on trace {}", k.metric, val, r.value("trace", -1));
        v.pass = false;
      }
    }
  }
  return v;
}

std::vector<int> brute_force_front(const SweepSpec& spec, const std::vector<bool>& pass) {
  const Grid g = make_grid(spec);
  std::set<int> s;
  for (int p = 0; p < g.points && p < static_cast<int>(pass.size()); ++p)
    if (pass[static_cast<std::size_t>(p)]) s.insert(p);
  return g.minimal(s);
}

bool cheaper_or_equal(const SweepSpec& spec, int a, int b) { return make_grid(spec).le(a, b); }

TuneResult run_tune(const SweepSpec& spec,
                    const std::function<std::vector<std::vector<nlohmann::json>>(const std::vector<int>&)>& evaluate) {
  if (!spec.tune.present || spec.tune.constraints.empty())
    throw InputError(spec.path, "no [tune] constraints (e.g. [tune] constraints = [\"popin.blurry_fraction_p99 <= 0.02\"])");
  if (!spec.configs.empty()) throw InputError(spec.path, "tune searches the [grid]: remove the [[configs]] tables");
  if (spec.grid.empty()) throw InputError(spec.path, "tune needs a [grid] to search");
  const Grid g = make_grid(spec);
  TuneResult res;
  res.grid = static_cast<std::size_t>(g.points);
  std::set<int> pass, fail;  // replayed
  std::set<int> candidates;  // passing, replayed or inferred: the cheapest of each staircase step
  const auto replay = [&](int p) {
    if (res.replayed.count(p)) return res.replayed[p].pass;
    const auto rows = evaluate({p});
    TuneVerdict v = judge(spec.tune, rows.at(0));
    (v.pass ? pass : fail).insert(p);
    res.replayed[p] = std::move(v);
    return res.replayed[p].pass;
  };
  const auto query = [&](int p) {
    if (res.replayed.count(p)) return res.replayed[p].pass;
    if (std::any_of(pass.begin(), pass.end(), [&](int f) { return g.le(f, p); })) return ++res.inferred, true;
    if (std::any_of(fail.begin(), fail.end(), [&](int f) { return g.le(p, f); })) return ++res.inferred, false;
    return replay(p);
  };

  // The walk axes: the two longest cost axes (x the longer); the other cost axes are layers.
  std::vector<int> cost_axes;
  for (std::size_t a = 0; a < g.n.size(); ++a)
    if (g.cost[a]) cost_axes.push_back(static_cast<int>(a));
  std::stable_sort(cost_axes.begin(), cost_axes.end(), [&](int a, int b) { return g.n[static_cast<std::size_t>(a)] > g.n[static_cast<std::size_t>(b)]; });
  const int ax = cost_axes.size() > 0 ? cost_axes[0] : -1, ay = cost_axes.size() > 1 ? cost_axes[1] : -1;
  // Every combination of the other axes (non-cost axes and layers), layers cheapest first: the
  // point order with the walk axes at 0 does it (first axis slowest).
  for (int p = 0; p < g.points; ++p) {
    std::vector<int> v = g.idx(p);
    if ((ax >= 0 && v[static_cast<std::size_t>(ax)] != 0) || (ay >= 0 && v[static_cast<std::size_t>(ay)] != 0)) continue;
    const auto at = [&](int x, int y) {
      if (ax >= 0) v[static_cast<std::size_t>(ax)] = x;
      if (ay >= 0) v[static_cast<std::size_t>(ay)] = y;
      return g.point(v);
    };
    if (ax < 0) {  // no cost axis: every config is its own front
      if (query(at(0, 0))) candidates.insert(at(0, 0));
      continue;
    }
    const int nx = g.n[static_cast<std::size_t>(ax)];
    if (ay < 0) {  // one cost axis: bisection for the cheapest passing value
      int lo = 0, hi = nx;  // the answer is in [lo, hi]; hi = nx: none passes
      while (lo < hi) {
        const int mid = (lo + hi) / 2;
        if (query(at(mid, 0))) hi = mid;
        else lo = mid + 1;
      }
      if (hi < nx) candidates.insert(at(hi, 0));
      continue;
    }
    const int ny = g.n[static_cast<std::size_t>(ay)];
    int y = ny - 1;
    for (int x = 0; x < nx; ++x) {
      while (y >= 0 && query(at(x, y))) --y;
      if (y + 1 < ny) candidates.insert(at(x, y + 1));
    }
  }

  // Check the front where monotonicity was assumed; a surprise joins the search.
  for (;;) {
    std::set<int> known = candidates;
    known.insert(pass.begin(), pass.end());
    bool changed = false;
    for (int p : g.minimal(known)) {
      if (!replay(p)) {  // inferred to pass, fails when replayed
        res.monotonicity_failures.push_back(p);
        candidates.erase(p);
        changed = true;
        break;
      }
      const std::vector<int> v = g.idx(p);
      for (std::size_t a = 0; a < v.size() && !changed; ++a) {
        if (!g.cost[a] || v[a] == 0) continue;
        std::vector<int> w = v;
        --w[a];
        const int q = g.point(w);
        // Under monotonicity the walk has shown q fails (replayed, or inferred from a failing
        // dearer config): a pass is a monotonicity failure, and p was not the cheapest.
        if (replay(q)) {
          res.monotonicity_failures.push_back(q);
          changed = true;
        }
      }
      if (changed) break;
    }
    if (!changed) break;
  }
  std::set<int> known = candidates;
  known.insert(pass.begin(), pass.end());
  for (int p : g.minimal(known))
    if (pass.count(p)) res.front.push_back(p);
  std::sort(res.front.begin(), res.front.end());
  std::sort(res.monotonicity_failures.begin(), res.monotonicity_failures.end());
  res.monotonicity_failures.erase(std::unique(res.monotonicity_failures.begin(), res.monotonicity_failures.end()),
                                  res.monotonicity_failures.end());
  return res;
}

int recommended_config(const SweepSpec& spec, const std::vector<int>& front) {
  const Grid g = make_grid(spec);
  int best = -1;
  double best_cost = 0;
  for (int p : front) {
    const std::vector<int> v = g.idx(p);
    double c = 0;
    for (std::size_t a = 0; a < v.size(); ++a)
      if (g.cost[a] && g.n[a] > 1) c += static_cast<double>(v[a]) / (g.n[a] - 1);
    if (best < 0 || c < best_cost) best = p, best_cost = c;
  }
  return best;
}

nlohmann::json tune_real_check(const SweepSpec& spec, const std::vector<Trace>& traces, int config,
                               const std::string& store_path) {
  const TileStore store = TileStore::open(store_path);
  ReplayConfig cfg = spec.points.at(static_cast<std::size_t>(config)).cfg;
  nlohmann::json out = {{"config", config}, {"store", store_path}, {"notes", bind_store_texture(cfg, store)}};
  const auto scene = make_scene_from_config(cfg);
  std::vector<nlohmann::json> sim_rows, real_rows;
  for (std::size_t t = 0; t < traces.size(); ++t) {
    ReplayEnv env;
    env.sizer = store_sizer(store);
    ReplayResult sim = run_replay(cfg, traces[t], *scene, env);
    RealRun real = run_real_replay(cfg, traces[t], *scene, store);
    sim_rows.push_back({{"status", "ok"}, {"trace", t}, {"summary", std::move(sim.summary)}});
    real_rows.push_back({{"status", "ok"}, {"trace", t}, {"summary", std::move(real.result.summary)}});
  }
  const TuneVerdict s = judge(spec.tune, sim_rows), r = judge(spec.tune, real_rows);
  out["sim_pass"] = s.pass;
  out["real_pass"] = r.pass;
  out["constraints"] = nlohmann::json::array();
  for (std::size_t c = 0; c < spec.tune.constraints.size(); ++c)
    out["constraints"].push_back({{"constraint", spec.tune.constraints[c].text},
                                  {"sim", s.worst[c]},
                                  {"real", r.worst[c]},
                                  {"gap", r.worst[c] - s.worst[c]}});
  return out;
}

}  // namespace vtsim
