// The one table of replacement policies: adding a policy is one file in impl/ and one line here.
#include "cache/policy/i_replacement.h"

namespace vtsim {

std::unique_ptr<IReplacementPolicy> make_policy_lru(std::uint64_t capacity);
std::unique_ptr<IReplacementPolicy> make_policy_level_lru(std::uint64_t capacity);

const Registry<ReplacementPolicyInfo>& replacement_policies() {
  static const Registry<ReplacementPolicyInfo> table(
      "replacement policy",
      {
          {"lru", "least recently used first (Mattson et al. 1970): today's default at both levels", make_policy_lru},
          {"level_lru", "LRU with each mip level counted 120 frames more recent: coarse fallback pages outlive fine ones (vtsim)", make_policy_level_lru},
      });
  return table;
}

std::unique_ptr<IReplacementPolicy> make_replacement_policy(std::string_view name, std::uint64_t capacity) {
  return replacement_policies().at(name).make(capacity);
}

}  // namespace vtsim
