// metrics.opt (sim/run/cache_bounds.h): each level's recorded accesses replayed offline beside the
// live run — Belady's bound below every policy, the run's own policy, LRU, the miss-ratio curve —
// without changing anything else the summary says.
#include <doctest/doctest.h>

#include <memory>
#include <string>

#include "cache/policy/belady.h"
#include "cache/policy/mrc.h"
#include "cache/policy/simulate.h"
#include "cache/policy/i_replacement.h"
#include "sim/run/cache_bounds.h"
#include "sim/report/report_html.h"
#include "sim/run/replay.h"
#include "sim/run/replay_config.h"
#include "sim/trace/trace_gen.h"
#include "sim/view/scene.h"

using namespace vtsim;

namespace {

Trace bounds_turn(double seconds) {
  TraceGenParams p = default_gen_params("turn");
  p.duration_s = seconds;
  p.event_s = seconds / 2;
  return generate_trace(p);
}

}  // namespace

TEST_CASE("metrics.opt: Belady's bound, the offline replays and the curve join the summary, and nothing else moves") {
  const Trace t = bounds_turn(3.0);
  for (const std::string policy : {"lru", "s3fifo", "level_lru"}) {
    CAPTURE(policy);
    const std::vector<std::string> sets = {"vt.pool_pages=96", "ram.capacity_MiB=4", "vt.pool_policy=" + policy};
    const ReplayConfig plain_cfg = load_replay_config("", sets, "vt");
    std::vector<std::string> opt_sets = sets;
    opt_sets.push_back("metrics.opt=true");
    const ReplayConfig opt_cfg = load_replay_config("", opt_sets, "vt");
    const std::unique_ptr<IScene> scene = make_scene_from_config(plain_cfg);
    nlohmann::json plain = run_replay(plain_cfg, t, *scene).summary;
    const ReplayResult opt_run = run_replay(opt_cfg, t, *scene);
    nlohmann::json opt = opt_run.summary;
    // The report draws both levels' curves; without metrics.opt it has none.
    const std::string html = html_report(opt, opt_run.metrics);
    CHECK(html.find("VT page pool: LRU miss-ratio curve") != std::string::npos);
    CHECK(html.find("RAM: LRU miss-ratio curve") != std::string::npos);
    CHECK(html_report(plain, opt_run.metrics).find("miss-ratio curve") == std::string::npos);
    REQUIRE(opt["vt"]["pool"].contains("bounds"));
    REQUIRE(opt["cache"].contains("ram_bounds"));
    const nlohmann::json pb = opt["vt"]["pool"]["bounds"], rb = opt["cache"]["ram_bounds"];
    // The pool: MIN is exact for unit pages, so no policy replayed offline misses less.
    CHECK(pb["policy"] == policy);
    CHECK(pb["opt_misses"].get<std::uint64_t>() <= pb["policy_offline_misses"].get<std::uint64_t>());
    CHECK(pb["opt_misses"].get<std::uint64_t>() <= pb["lru_offline_misses"].get<std::uint64_t>());
    CHECK(pb["accesses"].get<std::uint64_t>() + pb["accesses_locked"].get<std::uint64_t>() ==
          opt["vt"]["pool"]["hits"].get<std::uint64_t>() + opt["vt"]["pool"]["misses"].get<std::uint64_t>());
    CHECK(pb["capacity"].get<std::uint64_t>() == 96 - opt["vt"]["locked_pages"].get<std::uint64_t>());
    CHECK(pb["accesses_locked"].get<std::uint64_t>() > 0);
    // MIN with optional admission bounds the live pool too (its pinning only adds constraints).
    CHECK(pb["opt_misses"].get<std::uint64_t>() <= opt["vt"]["pool"]["misses"].get<std::uint64_t>());
    // RAM: PFOO-L <= Belady-Size, and PFOO-L is below every policy.
    CHECK(rb["opt_misses_lower"].get<std::uint64_t>() <= rb["opt_misses_upper"].get<std::uint64_t>());
    CHECK(rb["opt_misses_lower"].get<std::uint64_t>() <= rb["lru_offline_misses"].get<std::uint64_t>());
    CHECK(rb["accesses"].get<std::uint64_t>() ==
          opt["cache"]["ram_hits"].get<std::uint64_t>() + opt["cache"]["ram_misses"].get<std::uint64_t>());
    // The curve: 33 capacities from 0, miss ratios falling from 1.
    const auto& mrc = pb["mrc"];
    REQUIRE(mrc["capacity"].size() == 33);
    CHECK(mrc["unit"] == "pages");
    CHECK(mrc["miss_ratio"][0].get<double>() == 1.0);
    for (std::size_t i = 1; i < mrc["miss_ratio"].size(); ++i)
      CHECK(mrc["miss_ratio"][i].get<double>() <= mrc["miss_ratio"][i - 1].get<double>());
    // Everything else is as without metrics.opt (lock_from_level and bounds aside).
    opt["vt"]["pool"].erase("bounds");
    opt["cache"].erase("ram_bounds");
    opt.erase("run");
    plain.erase("run");
    CHECK(opt["config"]["metrics.opt"] == true);  // the one config key that differs
    opt["config"].erase("metrics.opt");
    plain["config"].erase("metrics.opt");
    CHECK(opt.dump() == plain.dump());
  }
}

TEST_CASE("level_bounds: on a hand-made pool log the figures are the offline functions' own") {
  AccessLog log;
  // Belady's textbook string (7 0 1 2 0 3 0 4 2 3 0 3 2 1 2 0 1 7 0 1) as level-0 pages, then a
  // locked page (level 9) that the bound drops.
  for (int k : {7, 0, 1, 2, 0, 3, 0, 4, 2, 3, 0, 3, 2, 1, 2, 0, 1, 7, 0, 1})
    log.accesses.push_back(Access{TileKey(0, 0, k, 0).bits, 1});
  log.accesses.push_back(Access{TileKey(0, 9, 0, 0).bits, 1});
  LevelBoundsInput in;
  in.policy = "lru";
  in.capacity = 3;
  in.pages = true;
  in.locked_from_level = 9;
  const nlohmann::json b = level_bounds(log, in);
  CHECK(b["accesses"] == 20);
  CHECK(b["accesses_locked"] == 1);
  CHECK(b["opt_misses"] == 8);  // no frames given: each access is one; MIN declining a key saves one of MIN's 9
  CHECK(b["lru_offline_misses"] == 12);  // LRU's textbook 12: a one-access frame pins only the missed key
  CHECK(b["policy_offline_misses"] == 12);
  // The curve covers the locked page too (its sizes read as pool slots): at 3 pages, LRU's 12 of
  // the 20 plus the locked page's one cold miss, of 21.
  const auto& cap = b["mrc"]["capacity"];
  for (std::size_t i = 0; i < cap.size(); ++i)
    if (cap[i] == 3) CHECK(b["mrc"]["miss_ratio"][i].get<double>() == doctest::Approx(13.0 / 21.0));
}

TEST_CASE("simulate_frames and belady_min_bypass: the pool's rules offline, and the bound under them") {
  // Each access its own frame: only the missed key is pinned, so simulate_frames is simulate.
  std::uint64_t state = 12345;
  const auto rnd = [&] { return (state = state * 6364136223846793005ull + 1442695040888963407ull) >> 33; };
  for (int seed = 0; seed < 20; ++seed) {
    std::vector<Access> acc;
    std::vector<std::uint64_t> every, frames;
    for (int i = 0; i < 600; ++i) acc.push_back(Access{rnd() % 40, 1});
    for (std::size_t i = 0; i < acc.size(); ++i) every.push_back(i);
    for (std::size_t i = 0; i < acc.size(); i += 1 + rnd() % 12) frames.push_back(i);
    for (std::uint64_t cap : {1u, 3u, 8u, 20u}) {
      CAPTURE(seed);
      CAPTURE(cap);
      for (const auto& e : replacement_policies().entries()) {
        CAPTURE(e.name);
        const auto p1 = make_replacement_policy(e.name, cap);
        const auto p2 = make_replacement_policy(e.name, cap);
        const SimStats a = simulate(acc, *p1, cap);
        const SimStats b = simulate_frames(acc, every, *p2, cap);
        if (e.name != "level_lru") {  // level_lru reads frames: one per access changes its order
          CHECK(a.misses == b.misses);
          CHECK(a.evictions == b.evictions);
        }
        // In frames, MIN with optional admission misses no more than any policy under the pool's rules.
        const auto p3 = make_replacement_policy(e.name, cap);
        CHECK(belady_min_bypass(acc, cap).misses <= simulate_frames(acc, frames, *p3, cap).misses);
      }
      CHECK(belady_min_bypass(acc, cap).misses <= belady_min(acc, cap).misses);
      CHECK(pfoo_lower(acc, cap).misses <= belady_min_bypass(acc, cap).misses);
    }
  }
  // A frame wanting more than the capacity: plain LRU cycles and misses every time, the pool's
  // rules keep what they hold and the rest go without.
  std::vector<Access> loop;
  std::vector<std::uint64_t> fs;
  for (int f = 0; f < 10; ++f) {
    fs.push_back(loop.size());
    for (std::uint64_t k = 0; k < 5; ++k) loop.push_back(Access{k, 1});
  }
  const auto lru = make_replacement_policy("lru", 4);
  CHECK(simulate(loop, "lru", 4).misses == 50);
  const SimStats framed = simulate_frames(loop, fs, *lru, 4);
  CHECK(framed.misses == 4 + 10);  // 4 cold, then key 4 goes without in every frame
  CHECK(framed.rejected == 10);
  CHECK(belady_min_bypass(loop, 4).misses == 14);
}
