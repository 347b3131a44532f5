#include "cache/policy/cachesim.h"

#include <fmt/format.h>

#include <cctype>
#include <cmath>
#include <stdexcept>
#include <string>

#include "cache/page_map.h"
#include "cache/policy/belady.h"
#include "cache/policy/i_replacement.h"
#include "core/error.h"
#include "core/registry.h"
#include "core/text.h"

namespace vtsim {

namespace {

std::string cachesim_shown(std::string_view t) {
  std::string s = t.size() > 40 ? std::string(t.substr(0, 40)) + "..." : std::string(t);
  for (char& c : s)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) == 0x7f) c = '?';
  return s;
}

struct CachesimUnitName {
  const char* name;
  std::uint64_t mult;
};
constexpr CachesimUnitName kCachesimUnits[] = {
    {"b", 1},
    {"kib", std::uint64_t{1} << 10}, {"mib", std::uint64_t{1} << 20}, {"gib", std::uint64_t{1} << 30}, {"tib", std::uint64_t{1} << 40},
    {"kb", 1000}, {"mb", 1000000}, {"gb", 1000000000}, {"tb", 1000000000000},
};

std::string cachesim_lower(std::string_view s) {
  std::string o(s);
  for (char& c : o) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return o;
}

const char* const kCachesimOffline[] = {"belady", "belady_reused", "pfoo_lower"};

std::string cachesim_json_string(std::string_view t) {
  std::string o = "\"";
  for (const char c : t) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      o += '\\';
      o += c;
    } else if (u < 0x20) {
      o += fmt::format("\\u{:04x}", u);
    } else {
      o += c;
    }
  }
  return o + "\"";
}

double cachesim_ratio(std::uint64_t a, std::uint64_t b) { return b ? static_cast<double>(a) / static_cast<double>(b) : 0.0; }

}  // namespace

CapacityList parse_capacity_list(std::string_view text, const std::string& where) {
  CapacityList list;
  if (text::trim(text).empty()) throw InputError(where, "no capacity given (e.g. 128MiB,256MiB or 1000,2000)");
  bool have_bytes = false, have_count = false;
  std::string first_bytes, first_count;
  while (true) {
    const std::size_t comma = text.find(',');
    const std::string_view raw = text.substr(0, comma);
    const std::string_view tok = text::trim(raw);
    if (tok.empty()) throw InputError(where, "an empty item (two commas in a row, or one at an end)");
    CapacityItem item;
    item.token = std::string(tok);
    std::size_t e = 0;
    while (e < tok.size() && (std::isdigit(static_cast<unsigned char>(tok[e])) || tok[e] == '.')) ++e;
    const std::string_view num = tok.substr(0, e), unit = text::trim(tok.substr(e));
    if (num.empty())
      throw InputError(where, fmt::format("'{}' does not start with a number (e.g. 128MiB, 1000, 0.1)", cachesim_shown(tok)));
    const bool has_point = num.find('.') != std::string_view::npos;
    if (unit.empty() && has_point) {  // a fraction of the footprint
      double f = 0;
      if (!text::parse_whole(num, f) || !(f > 0 && f <= 1))
        throw InputError(where, fmt::format("'{}': a fraction of the footprint is in (0, 1]", cachesim_shown(tok)));
      item.fraction = f;
    } else if (unit.empty()) {  // an object count
      std::uint64_t n = 0;
      if (!text::parse_whole(num, n) || n < 1 || n > kMaxPolicyCapacity)
        throw InputError(where, fmt::format("'{}': an object count is an integer in [1, 2^62]", cachesim_shown(tok)));
      item.value = n;
      if (!have_count) first_count = item.token;
      have_count = true;
    } else {
      const std::string u = cachesim_lower(unit);
      const CachesimUnitName* found = nullptr;
      for (const auto& k : kCachesimUnits)
        if (u == k.name) found = &k;
      if (found == nullptr)
        throw InputError(where, fmt::format("'{}': unknown unit '{}' (B, KiB, MiB, GiB, TiB, KB, MB, GB, TB; none: an "
                                            "object count)", cachesim_shown(tok), cachesim_shown(unit)));
      if (has_point) {
        double v = 0;
        if (!text::parse_whole(num, v) || !std::isfinite(v))
          throw InputError(where, fmt::format("'{}' is not a number and a unit", cachesim_shown(tok)));
        const double b = std::floor(v * static_cast<double>(found->mult));
        if (!(b >= 1) || b > static_cast<double>(kMaxPolicyCapacity))
          throw InputError(where, fmt::format("'{}' is outside [1 B, 2^62 B]", cachesim_shown(tok)));
        item.value = static_cast<std::uint64_t>(b);
      } else {
        std::uint64_t n = 0;
        if (!text::parse_whole(num, n) || n < 1 || n > kMaxPolicyCapacity / found->mult)
          throw InputError(where, fmt::format("'{}' is outside [1 B, 2^62 B]", cachesim_shown(tok)));
        item.value = n * found->mult;
      }
      if (!have_bytes) first_bytes = item.token;
      have_bytes = true;
    }
    list.items.push_back(std::move(item));
    if (list.items.size() > 10000) throw InputError(where, "more than 10000 capacities");
    if (comma == std::string_view::npos) break;
    text.remove_prefix(comma + 1);
  }
  if (have_bytes && have_count)
    throw InputError(where, fmt::format("'{}' is bytes and '{}' an object count: give one kind", first_bytes, first_count));
  list.unit_given = have_bytes || have_count;
  list.unit = have_count ? CapacityUnit::kObjects : CapacityUnit::kBytes;
  return list;
}

std::uint64_t access_footprint(std::span<const Access> accesses, CapacityUnit unit) {
  PageMap<std::uint64_t> last;
  for (const Access& a : accesses) {
    if (std::uint64_t* s = last.find(a.key)) *s = a.size;
    else last.put(a.key, a.size);
  }
  if (unit == CapacityUnit::kObjects) return last.size();
  std::uint64_t total = 0;
  last.for_each([&](std::uint64_t, const std::uint64_t& s) { total += s; });
  return total;
}

void resolve_capacities(CapacityList& list, std::uint64_t footprint, const std::string& where) {
  for (CapacityItem& it : list.items) {
    if (it.fraction <= 0) continue;
    const double v = std::floor(it.fraction * static_cast<double>(footprint));
    if (!(v >= 1))
      throw InputError(where, fmt::format("'{}' of a footprint of {} rounds to 0", it.token, footprint));
    it.value = static_cast<std::uint64_t>(v);
  }
}

std::vector<std::string> cachesim_policy_names() {
  std::vector<std::string> out;
  for (const auto& e : replacement_policies().entries()) out.emplace_back(e.name);
  for (const char* n : kCachesimOffline) out.emplace_back(n);
  return out;
}

void check_cachesim_policy(std::string_view name, const std::string& where) {
  const std::vector<std::string> names = cachesim_policy_names();
  for (const auto& n : names)
    if (n == name) return;
  std::vector<std::string_view> views(names.begin(), names.end());
  std::string all;
  for (const auto& n : names) all += (all.empty() ? "" : ", ") + n;
  std::string msg = fmt::format("unknown policy '{}' (one of: {}", cachesim_shown(name), all);
  const std::string close = closest_name(name, views);
  if (!close.empty()) msg += fmt::format("; did you mean '{}'?", close);
  throw InputError(where, msg + ")");
}

CacheSimResult cachesim_run(std::span<const Access> accesses, std::string_view policy, std::uint64_t capacity,
                            CapacityUnit unit) {
  check_cachesim_policy(policy, "policy");
  std::vector<Access> unit_copy;
  std::span<const Access> seq = accesses;
  if (unit == CapacityUnit::kObjects) {
    unit_copy.reserve(accesses.size());
    for (const Access& a : accesses) unit_copy.push_back(Access{a.key, 1});
    seq = unit_copy;
  }
  CacheSimResult r;
  for (const Access& a : seq) r.bytes_requested += a.size;
  if (policy == "belady") {
    r.stats = belady_size(seq, capacity);  // unit sizes: MIN on `capacity` frames
  } else if (policy == "belady_reused") {
    r.stats = belady_reused(seq, capacity);
  } else if (policy == "pfoo_lower") {
    const OptLowerBound b = pfoo_lower(seq, capacity);
    r.stats.requests = b.requests;
    r.stats.misses = b.misses;
    r.stats.hits = b.requests - b.misses;
    r.stats.bytes_missed = b.bytes_missed;
  } else {
    // libCacheSim's order (evict until the object fits, then insert), except for the two
    // policies whose eviction reads the missed key: ARC's REPLACE (its case and the B2
    // tie-break) and S3-FIFO's ghost hit, which libCacheSim takes before evicting too.
    const MissOrder order = policy == "arc" || policy == "s3fifo" ? MissOrder::kAdmitFirst : MissOrder::kEvictFirst;
    const auto p = make_replacement_policy(policy, capacity);
    r.stats = simulate(seq, *p, capacity, nullptr, order);
  }
  return r;
}

std::string cachesim_json(const CacheSimReport& rep) {
  const bool bytes = rep.unit == CapacityUnit::kBytes;
  std::string o = "{\n";
  o += fmt::format("  \"source\": {},\n  \"format\": {},\n  \"unit\": \"{}\",\n", cachesim_json_string(rep.source),
                   cachesim_json_string(rep.format), bytes ? "bytes" : "objects");
  o += fmt::format("  \"requests\": {},\n  \"objects\": {},\n  \"footprint\": {},\n  \"zero_size_skipped\": {},\n",
                   rep.requests, rep.objects, rep.footprint, rep.zero_size_skipped);
  o += "  \"rows\": [";
  for (std::size_t i = 0; i < rep.rows.size(); ++i) {
    const CacheSimRow& r = rep.rows[i];
    const SimStats& st = r.result.stats;
    const bool bound = r.policy == "pfoo_lower";
    o += i ? ",\n    {\n" : "\n    {\n";
    o += fmt::format("      \"policy\": {},\n      \"capacity\": {},\n      \"capacity_item\": {},\n",
                     cachesim_json_string(r.policy), r.capacity, cachesim_json_string(r.capacity_item));
    o += fmt::format("      \"requests\": {},\n      \"misses\": {},\n      \"miss_ratio\": {},\n      \"bound\": {}",
                     st.requests, st.misses, cachesim_ratio(st.misses, st.requests), bound ? "true" : "false");
    if (!bound) o += fmt::format(",\n      \"evictions\": {},\n      \"rejected\": {}", st.evictions, st.rejected);
    if (bytes)
      o += fmt::format(",\n      \"bytes_requested\": {},\n      \"miss_bytes\": {},\n      \"byte_miss_ratio\": {}",
                       r.result.bytes_requested, st.bytes_missed, cachesim_ratio(st.bytes_missed, r.result.bytes_requested));
    o += "\n    }";
  }
  o += rep.rows.empty() ? "]\n}\n" : "\n  ]\n}\n";
  return o;
}

std::string cachesim_csv(const CacheSimReport& rep) {
  const bool bytes = rep.unit == CapacityUnit::kBytes;
  std::string t = fmt::format("policy,capacity_{},requests,misses,miss_ratio{}\n", bytes ? "bytes" : "objects",
                              bytes ? ",bytes_requested,miss_bytes,byte_miss_ratio" : "");
  for (const CacheSimRow& r : rep.rows) {
    const SimStats& st = r.result.stats;
    t += fmt::format("{},{},{},{},{}", r.policy, r.capacity, st.requests, st.misses, cachesim_ratio(st.misses, st.requests));
    if (bytes)
      t += fmt::format(",{},{},{}", r.result.bytes_requested, st.bytes_missed,
                       cachesim_ratio(st.bytes_missed, r.result.bytes_requested));
    t += "\n";
  }
  return t;
}

}  // namespace vtsim
