// libCacheSim's trace formats (cache/policy/access_formats.h), the inputs of `vtsim cachesim`.
// The first byte picks the reader: even, oracleGeneral (the rest is the file); odd, CSV with the
// column options of its bits (header names or numbers, a size and time column, delimiter, text
// ids). An accepted oracleGeneral trace must write back to the same requests; every accepted
// trace must simulate under LRU and Belady at a small capacity, both units.
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "cache/policy/access_formats.h"
#include "cache/policy/cachesim.h"
#include "fuzz_targets.h"

namespace vtsim::fuzz {

void cachesim_formats(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return;
  const std::uint8_t mode = data[0];
  const std::string_view body(reinterpret_cast<const char*>(data + 1), size - 1);
  AccessLog log;
  bool accepted = false, oracle = (mode & 1u) == 0;
  expect_accept_or_reject("cachesim_formats", [&] {
    if (oracle) {
      log = parse_oracle_general(body, "fuzz").log;
    } else {
      // Columns from std::string constants: GCC 12 at -O3 reports a false -Wrestrict for a
      // string assigned from a choice of literals.
      static const std::string kId = "id", kSize = "size", kOne = "1", kTwo = "2", kThree = "3";
      CsvAccessOptions o;
      o.has_header = (mode & 2u) != 0;
      const bool names = o.has_header && (mode & 4u) != 0;
      o.obj_id_col = names ? kId : kOne;
      if (mode & 8u) o.obj_size_col = names ? kSize : kTwo;
      if (mode & 16u) o.time_col = kThree;
      o.delimiter = (mode & 32u) ? '\t' : ',';
      o.obj_id_is_num = (mode & 64u) == 0;
      log = parse_access_csv(body, "fuzz", o);
    }
    accepted = true;
  });
  if (!accepted) return;
  must_succeed("cachesim_formats", "round trip, simulation", [&] {
    if (oracle) {
      const AccessLog again = parse_oracle_general(format_oracle_general(log), "fuzz").log;
      bool same = again.accesses.size() == log.accesses.size();
      for (std::size_t i = 0; same && i < log.accesses.size(); ++i)
        same = again.accesses[i].key == log.accesses[i].key && again.accesses[i].size == log.accesses[i].size;
      if (!same) {
        std::fprintf(stderr, "vtsim fuzz cachesim_formats: the oracleGeneral round trip changed the requests\n");
        std::abort();
      }
    }
    for (const char* p : {"lru", "belady"})
      for (CapacityUnit u : {CapacityUnit::kObjects, CapacityUnit::kBytes}) {
        const CacheSimResult r = cachesim_run(log.accesses, p, 4096, u);
        if (r.stats.requests != log.accesses.size() || r.stats.misses > r.stats.requests) {
          std::fprintf(stderr, "vtsim fuzz cachesim_formats: counts out of range\n");
          std::abort();
        }
      }
  });
}

}  // namespace vtsim::fuzz
