// Steady-state rendering and aggregation allocate nothing: the global operator new of this test
// binary counts allocations (and forwards to malloc).
#include <doctest/doctest.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <string>

#include "stream/system/feedback.h"
#include "sim/run/popin.h"
#include "sim/view/scene.h"

namespace {
std::atomic<long> g_allocations{0};
}

// Every unaligned form is replaced, so that each allocation and its release pair up (malloc/free)
// also under ASan; the aligned forms keep the library's own pair.
void* operator new(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return ::operator new(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  return std::malloc(n ? n : 1);
}
void* operator new[](std::size_t n, const std::nothrow_t& t) noexcept { return ::operator new(n, t); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }

using namespace vtsim;

TEST_CASE("render, aggregate_feedback, add_level_seams and resident_levels allocate nothing after warm-up") {
  struct Flat final : IResidency {
    int resident_level(std::int64_t, std::int64_t, int d) const override { return d + 1; }
    int num_levels() const override { return 21; }
  } residency;
  for (const char* kind : {"plane", "heightfield", "town"}) {
    SceneConfig cfg;
    cfg.kind = kind;
    cfg.noise_posts = 129;
    cfg.spacing_m = 64.0;
    const auto scene = make_scene(cfg);
    ViewParams vp;
    ViewBuffer vb;
    std::vector<TileUse> tiles;
    std::vector<std::int8_t> levels;
    const Camera a = make_camera(pose_from_angles({40, 9, 30}, 20, -10), 1920, 1080);
    const Camera b = make_camera(pose_from_angles({60, 12, 2}, 50, -3), 1920, 1080);
    for (const Camera& c : {a, b}) {  // warm-up
      scene->render(c, vp, vb);
      aggregate_feedback(vb, 128, 21, tiles);
      add_level_seams(vb, 128, 21, tiles);
      resident_levels(vb, residency, levels);
    }
    const long before = g_allocations.load();
    for (const Camera& c : {a, b, a}) {
      scene->render(c, vp, vb);
      aggregate_feedback(vb, 128, 21, tiles);
      add_level_seams(vb, 128, 21, tiles);
      resident_levels(vb, residency, levels);
    }
    const long steady = g_allocations.load() - before;  // before CAPTURE, which allocates
    CAPTURE(std::string(kind));
    CHECK(steady == 0);
    CHECK(!vb.samples.empty());
  }
}
