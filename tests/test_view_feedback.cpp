#include <doctest/doctest.h>

#include <algorithm>
#include <map>
#include <stdexcept>

#include "stream/system/feedback.h"
#include "sim/run/popin.h"
#include "sim/view/scene.h"

using namespace vtsim;

namespace {

// Naive reference: a std::map over every sample.
std::vector<TileUse> naive(const ViewBuffer& vb, int tile, int levels) {
  std::map<std::uint64_t, std::uint32_t> m;
  for (const ViewSample& s : vb.samples) {
    const int l = desired_level(s.lod, levels);
    ++m[TileKey(0, static_cast<std::uint32_t>(l), (s.u >> l) / tile, (s.v >> l) / tile).bits];
  }
  std::vector<TileUse> out;
  for (const auto& [k, n] : m) {
    TileUse t;
    t.key.bits = k;
    t.samples = n;
    out.push_back(t);
  }
  return out;
}

bool same(const std::vector<TileUse>& a, const std::vector<TileUse>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (a[i].key != b[i].key || a[i].samples != b[i].samples) return false;
  return true;
}

// Levels finer than k are resident only within r level-l texels (Chebyshev) of (cu, cv): a
// clipmap-like residency; levels >= k everywhere.
struct RingResidency final : IResidency {
  std::int64_t cu, cv, r;
  int k, n;
  RingResidency(std::int64_t u, std::int64_t v, std::int64_t radius, int coarse, int levels)
      : cu(u), cv(v), r(radius), k(coarse), n(levels) {}
  int resident_level(std::int64_t u, std::int64_t v, int d) const override {
    for (int l = d; l < k; ++l)
      if (std::llabs((u >> l) - (cu >> l)) < r && std::llabs((v >> l) - (cv >> l)) < r) return l;
    return std::max(d, k);
  }
  int num_levels() const override { return n; }
};

}  // namespace

TEST_CASE("aggregate_feedback equals a naive map on rendered and synthetic buffers") {
  std::vector<TileUse> got;
  for (const char* kind : {"plane", "town"}) {
    SceneConfig cfg;
    cfg.kind = kind;
    const auto scene = make_scene(cfg);
    const int levels = mip_level_count(scene->texture());
    for (int div : {1, 8}) {
      ViewParams vp;
      vp.divisor = div;
      ViewBuffer vb;
      scene->render(make_camera(pose_from_angles({20, 30, 1.7}, 40, -8), 1920, 1080), vp, vb);
      REQUIRE(vb.samples.size() > 1000);
      for (int tile : {128, 100, 1, 4096}) {
        aggregate_feedback(vb, tile, levels, got);
        CHECK(same(got, naive(vb, tile, levels)));
      }
    }
  }
  // Synthetic: scattered samples, repeated tiles far apart in the buffer, huge texel coordinates.
  ViewBuffer vb;
  std::uint64_t s = 1;
  for (std::uint32_t i = 0; i < 50000; ++i) {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    ViewSample x;
    x.u = static_cast<std::int64_t>((s >> 20) % (std::uint64_t{1} << 34));
    x.v = static_cast<std::int64_t>((s >> 7) % 5000);
    x.lod = static_cast<float>((s >> 50) % 40) * 0.5f - 2.0f;
    x.pixel = i;
    vb.samples.push_back(x);
  }
  aggregate_feedback(vb, 128, 35, got);
  CHECK(same(got, naive(vb, 128, 35)));
  CHECK(got.size() > 1000);
  aggregate_feedback(ViewBuffer{}, 128, 21, got);
  CHECK(got.empty());
}

TEST_CASE("aggregate_feedback rejects bad arguments") {
  ViewBuffer vb;
  vb.samples.push_back(ViewSample{5, 5, 0.0f, 0});
  std::vector<TileUse> out;
  CHECK_THROWS_AS(aggregate_feedback(vb, 0, 21, out), std::invalid_argument);
  CHECK_THROWS_AS(aggregate_feedback(vb, 128, 0, out), std::invalid_argument);
  CHECK_THROWS_AS(aggregate_feedback(vb, 128, 65, out), std::invalid_argument);
  vb.samples[0].u = -1;
  CHECK_THROWS_AS(aggregate_feedback(vb, 128, 21, out), std::invalid_argument);
  vb.samples[0].u = std::int64_t{1} << 40;  // tile 2^33 at level 0 does not fit 27 bits
  CHECK_THROWS_AS(aggregate_feedback(vb, 128, 21, out), std::invalid_argument);
}

TEST_CASE("pop-in statistics: blurry fraction / mean deficit / visible pops") {
  ViewBuffer vb;
  // Desired levels 0, 1, 2, 3 (lod 0.5, 1.5, ...) at texels along u.
  for (int i = 0; i < 4; ++i)
    vb.samples.push_back(ViewSample{i * 1000, 0, static_cast<float>(i) + 0.5f, static_cast<std::uint32_t>(i)});
  const std::vector<std::int8_t> now = {0, 3, 2, 6};        // deficits 0, 2, 0, 3
  const std::vector<std::int8_t> before = {1, 3, 4, 6};     // sample 0 sharpened by 1, sample 2 by 2
  const PopinFrame f = popin_stats(vb, now, &before, 6);
  CHECK(f.samples == 4);
  CHECK(f.blurry == 2);
  CHECK(f.blurry_fraction == 0.5);
  CHECK(f.mean_deficit == 5.0 / 4.0);
  CHECK(f.visible_pops == 2);
  const PopinFrame g = popin_stats(vb, now, nullptr, 6);
  CHECK(g.visible_pops == 0);
  CHECK(g.blurry == 2);
  // Finer than desired (a level below d is resident) is not a negative deficit.
  const PopinFrame h = popin_stats(vb, {0, 0, 0, 0}, nullptr, 6);
  CHECK(h.blurry == 0);
  CHECK(h.mean_deficit == 0.0);
  const PopinFrame e = popin_stats(ViewBuffer{}, {}, nullptr, 6);
  CHECK(e.samples == 0);
  CHECK(e.blurry_fraction == 0.0);
  CHECK_THROWS_AS(popin_stats(vb, {0, 0}, nullptr, 6), std::invalid_argument);
  CHECK_THROWS_AS(popin_stats(vb, now, &now, 0), std::invalid_argument);
  const std::vector<std::int8_t> short_before = {1};
  CHECK_THROWS_AS(popin_stats(vb, now, &short_before, 6), std::invalid_argument);
}

TEST_CASE("resident_levels asks the residency with each sample's desired level") {
  ViewBuffer vb;
  vb.samples.push_back(ViewSample{100, 100, 0.2f, 0});    // d 0, near the centre
  vb.samples.push_back(ViewSample{100000, 100, 0.2f, 1}); // d 0, far: only coarse resident
  vb.samples.push_back(ViewSample{100000, 100, 7.9f, 2}); // d 7 >= k: resident as desired
  const RingResidency res(0, 0, 1000, 5, 21);
  std::vector<std::int8_t> lv;
  resident_levels(vb, res, lv);
  REQUIRE(lv.size() == 3);
  CHECK(lv[0] == 0);
  CHECK(lv[1] == 5);  // 100000 >> 4 = 6250 >= 1000 at every level < 5
  CHECK(lv[2] == 7);
  const PopinFrame f = popin_stats(vb, lv, nullptr, 21);
  CHECK(f.blurry == 1);
  CHECK(f.mean_deficit == 5.0 / 3.0);

  struct Broken final : IResidency {
    int n;
    explicit Broken(int levels) : n(levels) {}
    int resident_level(std::int64_t, std::int64_t, int) const override { return 99; }
    int num_levels() const override { return n; }
  };
  CHECK_THROWS_AS(resident_levels(vb, Broken(21), lv), std::invalid_argument);
  CHECK_THROWS_AS(resident_levels(vb, Broken(200), lv), std::invalid_argument);
}

TEST_CASE("add_level_seams: keeps the touched set / adds only sample-free tiles / recovers horizon levels") {
  const auto scene = make_scene(SceneConfig{});
  const int levels = mip_level_count(scene->texture());
  const Camera cam = make_camera(pose_from_angles({4096, 4096, 1.5}, 30, -2), 1920, 1080);
  ViewParams p1, p8;
  p1.divisor = 1;
  p8.divisor = 8;
  ViewBuffer b1, b8;
  scene->render(cam, p1, b1);
  scene->render(cam, p8, b8);
  std::vector<TileUse> ref, plain, seams;
  aggregate_feedback(b1, 128, levels, ref);
  aggregate_feedback(b8, 128, levels, plain);
  seams = plain;
  const std::size_t added = add_level_seams(b8, 128, levels, seams);
  CHECK(added == seams.size() - plain.size());
  CHECK(added > 0);
  CHECK(std::is_sorted(seams.begin(), seams.end(), [](const TileUse& a, const TileUse& b) { return a.key < b.key; }));
  std::map<std::uint64_t, std::uint32_t> in_seams;
  for (const TileUse& t : seams) in_seams[t.key.bits] = t.samples;
  CHECK(in_seams.size() == seams.size());  // no duplicates
  for (const TileUse& t : plain) CHECK(in_seams.at(t.key.bits) == t.samples);
  // Weighted miss against divisor 1, before and after.
  const auto missed = [&](const std::vector<TileUse>& ts) {
    std::map<std::uint64_t, int> have;
    for (const TileUse& t : ts) have[t.key.bits] = 1;
    double miss = 0, total = 0;
    for (const TileUse& t : ref) {
      total += t.samples;
      if (!have.count(t.key.bits)) miss += t.samples;
    }
    return miss / total;
  };
  CHECK(missed(plain) > 0.01);  // the low camera's horizon rows: one coarse level per row
  CHECK(missed(seams) < missed(plain) / 3);
  // Idempotent: a second call adds nothing new.
  CHECK(add_level_seams(b8, 128, levels, seams) == 0);
  // Divisor 1 buffers: neighbours are adjacent full-resolution pixels, so every added tile is one
  // the screen touches within a pixel of a sample; nothing is added across a silhouette.
  SceneConfig town;
  town.kind = "town";
  const auto t = make_scene(town);
  ViewBuffer tb;
  t->render(make_camera(pose_from_angles({30, 8, 1.7}, 0, -3), 640, 360), p8, tb);
  std::vector<TileUse> tt;
  aggregate_feedback(tb, 128, levels, tt);
  const std::size_t before = tt.size();
  add_level_seams(tb, 128, levels, tt);
  CHECK(tt.size() >= before);
  CHECK_THROWS_AS(add_level_seams(tb, 0, levels, tt), std::invalid_argument);
}
