// RAM LRU (src/cache/lru_cache.h) against the textbook std::list + std::unordered_map LRU, on the
// same key streams, side by side in one run. Target: >= 3x on lookups and inserts (issue 6).
// docs/bench.md and docs/cache.md carry the figures.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <list>
#include <optional>
#include <random>
#include <string>
#include <unordered_map>
#include <vector>

#include "cache/lru_cache.h"
#include "core/tile_key.h"
#include "harness.h"

namespace {

using vtsim::LruCache;
using vtsim::TileKey;
using vtsim::TileKeyHash;
namespace vb = vtsim::bench;

using Handle = std::uint64_t;  // what the engine stores: a decoded-buffer handle
using Hook = std::function<void(TileKey, Handle&, std::uint64_t)>;

// The textbook LRU: a list in recency order and a hash map from key to list node (one node
// allocation in each per insert). Same hash function, same hook, same hard byte cap.
class TextbookLru {
 public:
  TextbookLru(std::uint64_t capacity, Hook hook) : capacity_(capacity), hook_(std::move(hook)) {}

  Handle* get(TileKey k) {
    auto it = map_.find(k);
    if (it == map_.end()) return nullptr;
    list_.splice(list_.begin(), list_, it->second);
    return &it->second->value;
  }
  bool insert(TileKey k, Handle v, std::uint64_t bytes) {
    if (bytes > capacity_) return false;
    if (auto it = map_.find(k); it != map_.end()) {
      bytes_ -= it->second->bytes;
      list_.erase(it->second);
      map_.erase(it);
    }
    while (bytes > capacity_ - bytes_) {
      Entry& e = list_.back();
      bytes_ -= e.bytes;
      if (hook_) hook_(e.key, e.value, e.bytes);
      map_.erase(e.key);
      list_.pop_back();
    }
    list_.push_front({k, v, bytes});
    map_.emplace(k, list_.begin());
    bytes_ += bytes;
    return true;
  }
  std::size_t size() const { return map_.size(); }

 private:
  struct Entry {
    TileKey key;
    Handle value;
    std::uint64_t bytes;
  };
  std::uint64_t capacity_, bytes_ = 0;
  Hook hook_;
  std::list<Entry> list_;
  std::unordered_map<TileKey, std::list<Entry>::iterator, TileKeyHash> map_;
};

using Ours = LruCache<Handle>;

struct Counters {
  std::uint64_t hits = 0, evicted = 0, evicted_bytes = 0;
};

Ours make_ours(std::uint64_t capacity, Counters& c) {
  return Ours(capacity, [&c](TileKey, Handle&, std::uint64_t b, vtsim::LruRemoval) {
    ++c.evicted;
    c.evicted_bytes += b;
  });
}
TextbookLru make_ref(std::uint64_t capacity, Counters& c) {
  return TextbookLru(capacity, [&c](TileKey, Handle&, std::uint64_t b) {
    ++c.evicted;
    c.evicted_bytes += b;
  });
}

// Decoded 128x128 tiles: layer 0 albedo RGBA8 (64 KiB), 1 normal RG8 (32 KiB), 2 height R8 (16 KiB).
std::uint64_t tile_bytes(TileKey k) {
  static constexpr std::uint64_t kBytes[] = {65536, 32768, 16384};
  return kBytes[k.layer() % 3];
}

// Tile id -> a scattered tile (any layer 0-2, level 0-7, coordinates below 2^20).
TileKey tile_of(std::uint64_t id) {
  const std::uint64_t h = vtsim::mix64(id + 0x9e3779b97f4a7c15ULL);
  return TileKey(static_cast<std::uint32_t>(h % 3), static_cast<std::uint32_t>((h >> 8) % 8),
                 static_cast<std::int64_t>((h >> 16) & 0xFFFFF),
                 static_cast<std::int64_t>((h >> 40) & 0xFFFFF));
}

// Zipf(alpha) ranks 0..n-1 by inverse CDF: web-object and texture-page popularity is roughly
// Zipf with alpha 0.6-1.0 (Breslau et al., INFOCOM 1999); 0.9 sits in that range.
class Zipf {
 public:
  Zipf(std::size_t n, double alpha) : cdf_(n) {
    double sum = 0;
    for (std::size_t i = 0; i < n; ++i) cdf_[i] = sum += 1.0 / std::pow(static_cast<double>(i + 1), alpha);
    for (double& c : cdf_) c /= sum;
  }
  std::size_t operator()(std::mt19937_64& rng) const {
    const double u = std::uniform_real_distribution<double>(0, 1)(rng);
    const auto it = std::lower_bound(cdf_.begin(), cdf_.end(), u);
    return std::min<std::size_t>(static_cast<std::size_t>(it - cdf_.begin()), cdf_.size() - 1);
  }

 private:
  std::vector<double> cdf_;
};

// A clipmap-like moving window: each frame requests every tile of a w x w window around the
// camera at each of `levels` levels and each of 3 layers; the camera moves `speed` level-0 tiles
// per frame along a gently curving path (Yao 2007 §2: the clip stack follows the camera).
std::vector<TileKey> window_stream(std::size_t n, int w, int levels, double speed) {
  std::vector<TileKey> out;
  out.reserve(n);
  const double origin = 1 << 19;
  for (int frame = 0; out.size() < n; ++frame) {
    const double t = frame * speed;
    const double cx = origin + t, cy = origin + 40.0 * std::sin(t / 200.0);
    for (int level = 0; level < levels; ++level) {
      const auto x0 = static_cast<std::int64_t>(std::floor(cx / (1 << level))) - w / 2;
      const auto y0 = static_cast<std::int64_t>(std::floor(cy / (1 << level))) - w / 2;
      for (int dy = 0; dy < w; ++dy)
        for (int dx = 0; dx < w; ++dx)
          for (std::uint32_t layer = 0; layer < 3; ++layer)
            out.push_back(TileKey(layer, static_cast<std::uint32_t>(level), x0 + dx, y0 + dy));
    }
  }
  out.resize(n);
  return out;
}

// Fills a cache (and the same for the reference) to capacity with distinct tiles.
template <class C>
void fill(C& c, std::uint64_t capacity, std::uint64_t first_id, std::vector<TileKey>* resident = nullptr) {
  std::uint64_t used = 0;
  for (std::uint64_t id = first_id;; ++id) {
    const TileKey k = tile_of(id);
    if (used + tile_bytes(k) > capacity) break;
    c.insert(k, id, tile_bytes(k));
    used += tile_bytes(k);
    if (resident) resident->push_back(k);
  }
}

// get(); on a miss, insert(): the request loop of the RAM tier.
template <class C>
std::uint64_t replay(C& c, const std::vector<TileKey>& keys, std::size_t from, std::size_t to) {
  std::uint64_t hits = 0;
  for (std::size_t i = from; i < to; ++i) {
    const TileKey k = keys[i];
    if (Handle* h = c.get(k)) {
      ++hits;
      vb::do_not_optimize(*h);
    } else {
      c.insert(k, k.bits, tile_bytes(k));
    }
  }
  return hits;
}

[[noreturn]] void mismatch(const char* what) {
  std::fprintf(stderr, "bench_lru: ours and the textbook LRU disagree on %s: a bug\n", what);
  std::exit(3);
}

}  // namespace

int main(int argc, char** argv) {
  vb::Harness h("lru", argc, argv);
  const std::uint64_t capacity = h.pick<std::uint64_t>(1ull << 30, 128ull << 20);  // 1 GiB / 128 MiB
  const std::size_t n_ops = h.pick<std::size_t>(2'000'000, 500'000);
  const std::size_t n_warm = n_ops / 4;
  const std::size_t zipf_universe = h.pick<std::size_t>(1u << 20, 1u << 17);
  const double target = 3.0;
  h.param("capacity_bytes", capacity);
  h.param("tile_bytes", "64/32/16 KiB by layer (RGBA8/RG8/R8 128x128)");
  h.param("ops_per_rep", n_ops);
  h.param("hook", "both count evicted entries and bytes through a std::function");

  // --- lookups: a filled, aged cache; 90% of gets hit (Zipf over resident tiles), 10% miss.
  {
    Counters co, cr;
    Ours ours = make_ours(capacity, co);
    TextbookLru ref = make_ref(capacity, cr);
    // Age both: fill, then churn through twice the capacity so slab and heap are recycled.
    std::vector<TileKey> resident;
    fill(ours, capacity, 0);
    fill(ref, capacity, 0);
    std::mt19937_64 rng(1);
    const std::size_t churn = 2 * ours.size();
    for (std::size_t i = 0; i < churn; ++i) {
      const TileKey k = tile_of(1'000'000'000 + rng() % (4 * churn));
      ours.insert(k, 1, tile_bytes(k));
      ref.insert(k, 1, tile_bytes(k));
    }
    ours.for_each_lru_to_mru([&](TileKey k, const Handle&, std::uint64_t) { resident.push_back(k); });
    std::shuffle(resident.begin(), resident.end(), rng);
    const Zipf zipf(resident.size(), 0.9);
    std::vector<TileKey> keys(n_ops);
    for (TileKey& k : keys) k = rng() % 10 == 0 ? tile_of(3'000'000'000ull + rng()) : resident[zipf(rng)];
    std::uint64_t hits_o = 0, hits_r = 0;
    for (TileKey k : keys) {
      hits_o += ours.get(k) != nullptr;
      hits_r += ref.get(k) != nullptr;
    }
    if (hits_o != hits_r) mismatch("lookup hits");
    auto lookups = [&keys](auto& c) {
      return [&keys, &c] {
        std::uint64_t sum = 0;
        for (TileKey k : keys)
          if (const Handle* p = c.get(k)) sum += *p;
        vb::do_not_optimize(sum);
      };
    };
    h.compare({.name = "get_hit90_zipf",
               .work = static_cast<double>(n_ops),
               .params = {{"entries", ours.size()},
                          {"hit_ratio", static_cast<double>(hits_o) / static_cast<double>(n_ops)},
                          {"zipf_alpha", 0.9}},
               .target_ratio = target},
              {"lru_cache", {}, lookups(ours)}, {"list_unordered_map", {}, lookups(ref)});
  }

  // --- inserts that evict: a full cache takes a stream of new tiles; each evicts 1-4 entries.
  {
    const std::size_t n_ins = n_ops / 2;
    std::vector<TileKey> fresh(n_ins);
    for (std::size_t i = 0; i < n_ins; ++i) fresh[i] = tile_of(5'000'000'000ull + i);
    Counters co, cr;
    std::optional<Ours> ours;
    std::optional<TextbookLru> ref;
    auto inserts = [&fresh](auto& c) {
      return [&fresh, &c] {
        for (TileKey k : fresh) c->insert(k, k.bits, tile_bytes(k));
      };
    };
    // Setup (untimed): a fresh cache filled to capacity; warm-up sizes the slab once.
    auto setup_o = [&] {
      ours.reset();
      ours.emplace(make_ours(capacity, co));
      fill(*ours, capacity, 0);
    };
    auto setup_r = [&] {
      ref.reset();
      ref.emplace(make_ref(capacity, cr));
      fill(*ref, capacity, 0);
    };
    setup_o();
    setup_r();
    co = cr = {};
    inserts(ours)();
    inserts(ref)();
    if (co.evicted != cr.evicted || co.evicted_bytes != cr.evicted_bytes) mismatch("evictions");
    h.compare({.name = "insert_evict",
               .work = static_cast<double>(n_ins),
               .params = {{"inserts", n_ins},
                          {"evictions_per_insert",
                           static_cast<double>(co.evicted) / static_cast<double>(n_ins)}},
               .target_ratio = target},
              {"lru_cache", setup_o, inserts(ours)}, {"list_unordered_map", setup_r, inserts(ref)});
  }

  // --- mixed: get, insert on miss, on three streams; the first quarter warms the cache (untimed).
  struct Stream {
    const char* name;
    std::vector<TileKey> keys;
    nlohmann::json params;
  };
  std::vector<Stream> streams;
  {
    std::mt19937_64 rng(2);
    const Zipf zipf(zipf_universe, 0.9);
    std::vector<TileKey> z(n_warm + n_ops);
    for (TileKey& k : z) k = tile_of(zipf(rng));
    streams.push_back({"zipf", std::move(z), {{"universe", zipf_universe}, {"zipf_alpha", 0.9}}});
    const int w = 12, levels = 6;
    const double speed = 0.3;
    streams.push_back({"window", window_stream(n_warm + n_ops, w, levels, speed),
                       {{"window_tiles", w}, {"levels", levels}, {"layers", 3}, {"tiles_per_frame", speed}}});
    // Uniform over 4x the tiles that fit: hit ratio about 1/4 (the scan-like worst case).
    const std::uint64_t mean_tile_bytes = (65536 + 32768 + 16384) / 3;
    const std::size_t universe = 4 * static_cast<std::size_t>(capacity / mean_tile_bytes);
    std::vector<TileKey> u(n_warm + n_ops);
    for (TileKey& k : u) k = tile_of(rng() % universe);
    streams.push_back({"uniform", std::move(u), {{"universe", universe}}});
  }
  for (Stream& s : streams) {
    const std::string name = std::string("mixed_") + s.name;
    if (!h.selected(name)) continue;
    Counters co, cr;
    std::optional<Ours> ours;
    std::optional<TextbookLru> ref;
    const auto& keys = s.keys;
    auto setup_o = [&] {
      ours.reset();
      ours.emplace(make_ours(capacity, co));
      replay(*ours, keys, 0, n_warm);
    };
    auto setup_r = [&] {
      ref.reset();
      ref.emplace(make_ref(capacity, cr));
      replay(*ref, keys, 0, n_warm);
    };
    setup_o();
    setup_r();
    const std::uint64_t hits_o = replay(*ours, keys, n_warm, keys.size());
    const std::uint64_t hits_r = replay(*ref, keys, n_warm, keys.size());
    if (hits_o != hits_r || co.evicted != cr.evicted) mismatch(name.c_str());
    nlohmann::json params = s.params;
    params["hit_ratio"] = static_cast<double>(hits_o) / static_cast<double>(n_ops);
    params["warm_ops"] = n_warm;
    auto run_o = [&] { vb::do_not_optimize(replay(*ours, keys, n_warm, keys.size())); };
    auto run_r = [&] { vb::do_not_optimize(replay(*ref, keys, n_warm, keys.size())); };
    h.compare({.name = name, .work = static_cast<double>(n_ops), .params = params, .target_ratio = target},
              {"lru_cache", setup_o, run_o}, {"list_unordered_map", setup_r, run_r});
  }
  return h.finish();
}
