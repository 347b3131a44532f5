// VtSystem on hand-made feedback: the wanted set (samples' pages, ancestors, locked levels),
// coarse-first requests, commits and the page-table fallback the screen samples, the clamp and
// the sampling bias, the pool budget and priority under pressure.
#include <doctest/doctest.h>

#include <algorithm>
#include <set>

#include "core/view_spans.h"
#include "stream/system/vt_system.h"

using namespace vtsim;

namespace {

// 4096² texels, 128-texel pages: 6 levels of 32, 16, 8, 4, 2, 1 pages a side.
// A system's two inputs (stream/system/i_system.h, vt_system.h).
struct VtParams {
  SystemSetup s;
  VtConfig c;
};
VtParams small_params(std::uint32_t pool = 64, int layers = 1) {
  VtParams p;
  p.s.extent = {4096, 4096};
  p.s.tile_size = 128;
  p.s.border = 0;
  p.s.layers = layers;
  p.s.tile_bytes_all_layers = 65536u * static_cast<std::uint64_t>(layers);
  p.c.pool_pages = pool;
  p.c.locked_levels = 1;
  return p;
}

std::unique_ptr<VtSystem> make_vt(const VtParams& p) { return std::make_unique<VtSystem>(p.s, p.c); }

ViewSample sample(std::int64_t u, std::int64_t v, float lod, std::uint32_t pixel = 0) {
  ViewSample s;
  s.u = u;
  s.v = v;
  s.lod = lod;
  s.pixel = pixel;
  return s;
}

// One frame: feedback in, throttle decision, needs out.
std::vector<Need> frame(VtSystem& vt, int f, const ViewBuffer* vb, const ThrottleDecision& d = {}) {
  SystemFrame sf;
  sf.frame = f;
  sf.view = vb;
  vt.begin_frame(sf);
  vt.apply_throttle(d);
  std::vector<Need> needs;
  vt.emit_needs(needs);
  return needs;
}

std::set<std::uint64_t> keys(const std::vector<Need>& needs) {
  std::set<std::uint64_t> s;
  for (const Need& n : needs) s.insert(n.key.bits);
  return s;
}

}  // namespace

TEST_CASE("vt system: the view wants its samples' pages, every ancestor and the locked level") {
  const VtParams vt_p = small_params();
  VtSystem vt(vt_p.s, vt_p.c);
  CHECK(vt.num_levels() == 6);
  ViewBuffer vb;
  vb.samples = {sample(3 * 128 + 5, 3 * 128 + 9, 0.5f, 0), sample(3 * 128 + 100, 3 * 128 + 1, 0.9f, 1),
                sample(0 * 512 + 10, 1 * 512 + 40, 2.2f, 2)};
  const auto needs = frame(vt, 0, &vb);
  // Level 0 (3,3); level 1 (1,1); level 2 (0,0) [ancestor] and (0,1) [desired]; levels 3, 4, 5
  // page (0,0) — level 5 is also the locked level.
  const std::set<std::uint64_t> expect = {page_key(0, 3, 3).bits, page_key(1, 1, 1).bits, page_key(2, 0, 0).bits,
                                          page_key(2, 0, 1).bits, page_key(3, 0, 0).bits, page_key(4, 0, 0).bits,
                                          page_key(5, 0, 0).bits};
  CHECK(keys(needs) == expect);
  REQUIRE(vt.wanted().size() == 7);
  CHECK(vt.wanted().front().page == page_key(5, 0, 0));  // coarsest first
  CHECK(vt.wanted().front().samples == 3);               // every sample falls back to it
  // Coarse before fine: priorities never decrease with the level getting finer.
  std::vector<Need> sorted = needs;
  std::sort(sorted.begin(), sorted.end(), [](const Need& a, const Need& b) { return a.priority < b.priority; });
  for (std::size_t i = 1; i < sorted.size(); ++i) CHECK(sorted[i - 1].key.level() >= sorted[i].key.level());
  CHECK(vt.frame_counts().visible_pages == 7);
  CHECK(vt.frame_counts().requested_pages == 7);
  CHECK(vt.pool().reservations() == 7);
  CHECK(vt.pool_pressure() == doctest::Approx(7.0 / 64.0));

  // Nothing resident: the screen has nothing to sample.
  CHECK(vt.resident_level(3 * 128 + 5, 3 * 128 + 9, 0) == 6);
  // The coarsest page arrives: every sample falls back to it.
  CHECK(vt.commit(TileKey(0, 5, 0, 0), 0));
  CHECK(vt.resident_level(3 * 128 + 5, 3 * 128 + 9, 0) == 5);
  CHECK(vt.commit(TileKey(0, 2, 0, 0), 0));
  CHECK(vt.resident_level(3 * 128 + 5, 3 * 128 + 9, 0) == 2);
  for (const Need& n : needs) vt.commit(n.key, 0);
  CHECK(vt.resident_level(3 * 128 + 5, 3 * 128 + 9, 0) == 0);
  CHECK(vt.resident_level(10, 512 + 40, 2) == 2);
  CHECK(vt.resident_level(4000, 4000, 0) == 5);  // elsewhere: the locked root
  CHECK(vt.page_table().mapped_pages() == 7);
  // The same view next frame requests nothing.
  CHECK(frame(vt, 1, &vb).empty());
  CHECK(vt.frame_counts().visible_resident == 7);
  CHECK(vt.commit(TileKey(0, 0, 9, 9), 1) == false);  // never requested: a stale upload
}

TEST_CASE("vt system: prioritised by level gap × samples within a level (RAGE)") {
  const VtParams vt_p = small_params();
  VtSystem vt(vt_p.s, vt_p.c);
  ViewBuffer vb;
  // Two level-0 pages: (0,0) with 1 sample, (20,20) with 5 samples.
  vb.samples = {sample(10, 10, 0.0f)};
  for (int i = 0; i < 5; ++i) vb.samples.push_back(sample(20 * 128 + i, 20 * 128, 0.0f, static_cast<std::uint32_t>(1 + i)));
  auto needs = frame(vt, 0, &vb);
  std::uint64_t p_few = 0, p_many = 0;
  for (const Need& n : needs) {
    if (n.key == TileKey(0, 0, 0, 0)) p_few = n.priority;
    if (n.key == TileKey(0, 0, 20, 20)) p_many = n.priority;
  }
  CHECK(p_many < p_few);  // more samples waiting: sooner
  // Make level 1 page (0,0) resident: page (0,0) now has a gap of 1, (20,20) still a gap of 6.
  for (const Need& n : needs)
    if (n.key.level() >= 1) vt.commit(n.key, 0);
  vb.samples.resize(1);
  vb.samples.push_back(sample(20 * 128, 20 * 128, 0.0f, 9));  // 1 sample each now
  needs = frame(vt, 1, &vb);
  for (const Need& n : needs) {
    if (n.key == TileKey(0, 0, 0, 0)) p_few = n.priority;
    if (n.key == TileKey(0, 0, 20, 20)) p_many = n.priority;
  }
  CHECK(p_many == p_few);  // (20,20)'s ancestors were all committed too: same gap, same samples
}

TEST_CASE("vt system: the clamp and the sampling bias apply to requests and to what the screen samples") {
  const VtParams vt_p = small_params();
  VtSystem vt(vt_p.s, vt_p.c);
  ViewBuffer vb;
  vb.samples = {sample(100, 100, 0.0f)};
  auto needs = frame(vt, 0, &vb);
  for (const Need& n : needs) vt.commit(n.key, 0);
  CHECK(vt.resident_level(100, 100, 0) == 0);
  ThrottleDecision clamp2;
  clamp2.clamp = 2;
  needs = frame(vt, 1, &vb, clamp2);
  CHECK(needs.empty());
  CHECK(vt.resident_level(100, 100, 0) == 2);  // level 0 and 1 stay resident but are not sampled
  CHECK(vt.frame_counts().visible_pages == 4);  // levels 2..5
  ThrottleDecision sb;
  sb.sample_bias = 1.0;
  frame(vt, 2, &vb, sb);
  CHECK(vt.resident_level(100, 100, 0) == 1);
  CHECK(vt.resident_level(100, 100, 4) == 5);
  // The batch form sees each sample's lod: a fractional sampling bias is exact, floor(lod + 0.5).
  ThrottleDecision half;
  half.sample_bias = 0.5;
  frame(vt, 3, &vb, half);
  const ViewSample two[] = {sample(100, 100, 0.3f), sample(100, 100, 0.8f)};
  std::int8_t lv[2] = {-1, -1};
  vt.resident_levels(two, 2, lv);
  CHECK(lv[0] == 0);
  CHECK(lv[1] == 1);
  CHECK(vt.resident_level(100, 100, 0) == 1);  // the scalar form rounds 0.5 up to a whole level
  ThrottleDecision over;
  over.clamp = 99;  // beyond the coarsest clamp: held at the locked level
  frame(vt, 3, &vb, over);
  CHECK(vt.clamp() == vt.coarsest_clamp());
  CHECK(vt.coarsest_clamp() == 5);

  // A feedback bias moves the requests, not the sampling.
  const VtParams b_p = small_params();
  VtSystem b(b_p.s, b_p.c);
  ThrottleDecision fb;
  fb.bias = 1.5;  // floor(0 + 1.5) = level 1
  needs = frame(b, 0, &vb, fb);
  for (const Need& n : needs) CHECK(n.key.level() >= 1);
  for (const Need& n : needs) b.commit(n.key, 0);
  CHECK(b.resident_level(100, 100, 0) == 1);
  CHECK(b.bias() == 1.5);
}

TEST_CASE("vt system: a pool smaller than the view throttles the finest pages and never overflows") {
  const VtParams vt_p = small_params(/*pool=*/12);
  VtSystem vt(vt_p.s, vt_p.c);
  ViewBuffer vb;
  // 32 level-0 pages along a row: with ancestors 32 + 16 + 8 + 4 + 2 + 1 = 63 pages wanted.
  for (int i = 0; i < 32; ++i) vb.samples.push_back(sample(i * 128 + 1, 1, 0.0f, static_cast<std::uint32_t>(i)));
  for (int f = 0; f < 20; ++f) {
    const auto needs = frame(vt, f, &vb);
    CHECK(vt.pool().occupied() <= 12);
    for (const Need& n : needs) vt.commit(n.key, f);
    CHECK(vt.pool().occupied() <= 12);
  }
  CHECK(vt.pool_pressure() == doctest::Approx(63.0 / 12.0));
  CHECK(vt.frame_counts().throttled_pages == 63 - 12);
  // Coarse first: the 12 slots hold levels 5..2 (1 + 2 + 4 + ... no: 1 + 2 + 4 + 8 = 15 > 12),
  // so every page of levels 5, 4, 3 (7 pages) and 5 of level 2.
  int coarse = 0;
  for (const auto& w : vt.wanted())
    if (vt.pool().resident(w.page)) coarse += w.page.level() >= 3;
  CHECK(coarse == 7);
  CHECK(vt.pool().stats().evictions == 0);  // nothing thrashed: pages in use are never victims
  CHECK(vt.throttled_needs() == 51);
}

TEST_CASE("vt system: a higher-priority page takes a lower one's reservation when the pool is short") {
  const VtParams vt_p = small_params(/*pool=*/3);
  VtSystem vt(vt_p.s, vt_p.c);
  ViewBuffer vb;
  vb.samples = {sample(1, 1, 5.0f)};  // only the root (level 5)
  auto needs = frame(vt, 0, &vb);
  REQUIRE(needs.size() == 1);
  vt.commit(needs[0].key, 0);
  // A level-0 view: 6 pages wanted, 2 free slots: levels 4 and 3 reserve them.
  vb.samples = {sample(1, 1, 0.0f)};
  needs = frame(vt, 1, &vb);
  CHECK(keys(needs) == std::set<std::uint64_t>{page_key(4, 0, 0).bits, page_key(3, 0, 0).bits});
  // A sample far away adds its own chain, whose level-4 page (1,1) outranks level 3 (0,0): with no
  // free slot and nothing evictable (the root is locked), it takes level 3's reservation.
  vb.samples = {sample(1, 1, 0.0f), sample(3000, 3000, 1.0f, 1)};
  needs = frame(vt, 2, &vb);
  CHECK(keys(needs) == std::set<std::uint64_t>{page_key(4, 0, 0).bits, page_key(4, 1, 1).bits});
  CHECK(vt.pool().reservations() == 2);
}

TEST_CASE("vt system: multi-layer pages map only when every layer is resident") {
  const VtParams vt_p = small_params(16, 2);
  VtSystem vt(vt_p.s, vt_p.c);
  ViewBuffer vb;
  vb.samples = {sample(1, 1, 4.0f)};
  const auto needs = frame(vt, 0, &vb);
  CHECK(needs.size() == 4);  // levels 4 and 5, two layers each
  CHECK(vt.commit(TileKey(1, 5, 0, 0), 0));
  CHECK(vt.resident_level(1, 1, 4) == 6);
  CHECK(frame(vt, 1, &vb).size() == 3);  // the missing layer of level 5 and both of level 4
  CHECK(vt.commit(TileKey(0, 5, 0, 0), 1));
  CHECK(vt.resident_level(1, 1, 4) == 5);
  std::vector<std::uint64_t> missing;
  frame(vt, 2, &vb);
  vt.missing_bytes_by_level(missing);
  REQUIRE(missing.size() == 6);
  CHECK(missing[5] == 0);
  CHECK(missing[4] == 2 * 65536);
}

TEST_CASE("vt system: bad parameters are refused") {
  CHECK_THROWS_AS(make_vt([] { auto p = small_params(); p.s.tile_size = 127; return p; }()), std::invalid_argument);
  CHECK_THROWS_AS(make_vt([] { auto p = small_params(); p.c.locked_levels = 7; return p; }()), std::invalid_argument);
  CHECK_THROWS_AS(make_vt([] { auto p = small_params(4); p.c.locked_levels = 2; return p; }()), std::invalid_argument);  // 5 locked pages
  CHECK_NOTHROW(make_vt([] { auto p = small_params(5); p.c.locked_levels = 2; return p; }()));
  CHECK_THROWS_AS(make_vt([] { auto p = small_params(); p.c.prefetch_finer_levels = 3; return p; }()), std::invalid_argument);
}

TEST_CASE("vt system: prefetch asks for the finer children of desired pages, into RAM only") {
  auto p = small_params();
  p.c.prefetch_finer_levels = 2;
  VtSystem vt(p.s, p.c);
  ViewBuffer vb;
  vb.samples = {sample(700, 700, 3.0f)};  // level 3 page (0,0): 4 children at level 2, 16 at level 1
  const auto needs = frame(vt, 0, &vb);
  std::size_t prefetch = 0;
  for (const Need& n : needs)
    if (n.prefetch) {
      ++prefetch;
      CHECK((n.key.level() == 2 || n.key.level() == 1));
    }
  CHECK(prefetch == 4 + 16);
  CHECK(vt.frame_counts().prefetch_pages == 20);
}

TEST_CASE("vt system: spans give the same wanted pages, requests and resident levels as their samples") {
  // Rows of samples whose texel and lod drift along the row, as a rendered surface's do, so that
  // spans run over several samples and break at pages, levels and rows.
  std::uint64_t seed = 12345;
  const auto rnd = [&](std::uint64_t n) {
    seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
    return (seed >> 33) % n;
  };
  SpanBuffer sb;
  sb.block_shift = 7;  // spans cut at 128-texel pages, as the frame loop does for 128-texel pages
  sb.levels = 13;      // mip levels of a 4096² texture
  const int width = 40;
  for (int y = 0; y < 30; ++y) {
    double u = static_cast<double>(rnd(4096)), v = static_cast<double>(rnd(4096)), lod = static_cast<double>(rnd(500)) / 100.0;
    const double du = static_cast<double>(rnd(200)) - 100.0, dl = (static_cast<double>(rnd(100)) - 50.0) / 400.0;
    for (int x = 0; x < width; ++x) {
      if (rnd(10) == 0) continue;  // a pixel without a sample
      u = std::clamp(u + du, 0.0, 4095.0);
      lod = std::clamp(lod + dl, -1.0, 7.0);
      sb.view.samples.push_back(sample(static_cast<std::int64_t>(u), static_cast<std::int64_t>(v),
                                       static_cast<float>(lod), static_cast<std::uint32_t>(y * width + x)));
    }
  }
  sb.view.width = width;
  sb.has_samples = true;
  spans_from_samples(sb.view, sb.levels, sb.block_shift, sb.spans);
  REQUIRE(sb.spans.size() < sb.view.samples.size() / 2);  // runs of several samples
  for (const ThrottleDecision& d : {ThrottleDecision{}, ThrottleDecision{2, 0.0, 0.0, ""}, ThrottleDecision{0, 1.5, 0.0, ""},
                                    ThrottleDecision{0, 0.0, 1.0, ""}}) {
    CAPTURE(d.clamp);
    CAPTURE(d.bias);
    CAPTURE(d.sample_bias);
    const VtParams p = small_params(256);
    VtSystem with_spans(p.s, p.c), per_sample(p.s, p.c);
    SystemFrame a, b;
    a.view = &sb.view;
    a.spans = &sb;
    b.view = &sb.view;
    std::vector<Need> na, nb;
    for (int f = 0; f < 3; ++f) {
      a.frame = b.frame = f;
      with_spans.begin_frame(a);
      per_sample.begin_frame(b);
      with_spans.apply_throttle(d);
      per_sample.apply_throttle(d);
      na.clear();
      nb.clear();
      with_spans.emit_needs(na);
      per_sample.emit_needs(nb);
      REQUIRE(with_spans.wanted().size() == per_sample.wanted().size());
      for (std::size_t i = 0; i < with_spans.wanted().size(); ++i) {
        CHECK(with_spans.wanted()[i].page == per_sample.wanted()[i].page);
        CHECK(with_spans.wanted()[i].samples == per_sample.wanted()[i].samples);
        CHECK(with_spans.wanted()[i].desired == per_sample.wanted()[i].desired);
      }
      REQUIRE(na.size() == nb.size());
      for (std::size_t i = 0; i < na.size(); ++i) CHECK(na[i].key == nb[i].key);
      // Commit every other need: the page table falls back unevenly.
      for (std::size_t i = 0; i < na.size(); i += 2) {
        with_spans.commit(na[i].key, f);
        per_sample.commit(na[i].key, f);
      }
      std::vector<std::int8_t> span_lv(sb.spans.size()), sample_lv(sb.view.samples.size());
      with_spans.span_resident_levels(sb.spans.data(), sb.spans.size(), span_lv.data());
      per_sample.resident_levels(sb.view.samples.data(), sb.view.samples.size(), sample_lv.data());
      std::size_t resolved = 0;
      for (std::size_t i = 0; i < sb.spans.size(); ++i) {
        if (span_lv[i] == -1) continue;
        ++resolved;
        for (std::uint32_t k = 0; k < sb.spans[i].count; ++k) CHECK(span_lv[i] == sample_lv[sb.spans[i].first + k]);
      }
      // Without a sampling bias every span resolves at once; with one, none does.
      CHECK(resolved == (d.sample_bias == 0.0 ? sb.spans.size() : 0));
    }
  }
}
