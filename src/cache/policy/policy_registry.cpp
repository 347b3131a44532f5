// The one table of replacement policies: adding a policy is one file in impl/ and one line here.
#include "cache/policy/i_replacement.h"

namespace vtsim {

std::unique_ptr<IReplacementPolicy> make_policy_lru(std::uint64_t capacity);
std::unique_ptr<IReplacementPolicy> make_policy_clock(std::uint64_t capacity);
std::unique_ptr<IReplacementPolicy> make_policy_s3fifo(std::uint64_t capacity);
std::unique_ptr<IReplacementPolicy> make_policy_arc(std::uint64_t capacity);
std::unique_ptr<IReplacementPolicy> make_policy_level_lru(std::uint64_t capacity);
std::unique_ptr<IReplacementPolicy> make_policy_fifo(std::uint64_t capacity);

const Registry<ReplacementPolicyInfo>& replacement_policies() {
  static const Registry<ReplacementPolicyInfo> table(
      "replacement policy",
      {
          {"lru", "least recently used first (Mattson et al. 1970): today's default at both levels", make_policy_lru},
          {"clock", "second chance on a ring of reference bits (Corbató 1968): LRU's hits for a bit set per hit", make_policy_clock},
          {"s3fifo", "small, main and ghost FIFOs (Yang et al., SOSP 2023): keys seen once leave early, scans pass through", make_policy_s3fifo},
          {"arc", "recency and frequency lists with ghost-tuned split (Megiddo and Modha, FAST 2003)", make_policy_arc},
          {"level_lru", "LRU with each mip level counted 120 frames more recent: coarse fallback pages outlive fine ones (vtsim)", make_policy_level_lru},
          {"fifo", "first in, first out: a hit changes nothing (libCacheSim's FIFO); the baseline the others are measured against", make_policy_fifo},
      });
  return table;
}

std::unique_ptr<IReplacementPolicy> make_replacement_policy(std::string_view name, std::uint64_t capacity) {
  return replacement_policies().at(name).make(capacity);
}

}  // namespace vtsim
