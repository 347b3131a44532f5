#include "core/registry.h"

namespace vtsim {

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j)
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0u : 1u)});
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string closest_name(std::string_view word, const std::vector<std::string_view>& candidates) {
  // Below 4 edits, and at most half the shorter string: "foo" is not a typo of "none".
  std::size_t best = 4;
  std::string_view best_name;
  for (std::string_view c : candidates) {
    // The distance is at least the difference in length: a long word costs nothing here.
    const std::size_t diff = word.size() > c.size() ? word.size() - c.size() : c.size() - word.size();
    if (diff >= best) continue;
    const std::size_t d = edit_distance(word, c);
    if (d < best && 2 * d <= std::min(word.size(), c.size())) best = d, best_name = c;
  }
  return std::string(best_name);
}

}  // namespace vtsim
