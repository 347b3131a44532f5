#include "sim/run/metric_path.h"

#include "core/text.h"

namespace vtsim {

const nlohmann::json* summary_path(const nlohmann::json& summary, std::string_view path) {
  const nlohmann::json* p = &summary;
  for (;;) {
    const std::size_t dot = path.find('.');
    const std::string part(path.substr(0, dot));
    if (p->is_object()) {
      const auto it = p->find(part);
      if (it == p->end()) return nullptr;
      p = &*it;
    } else if (p->is_array()) {
      std::size_t i = 0;
      if (!text::parse_whole(part, i) || i >= p->size()) return nullptr;
      p = &(*p)[i];
    } else {
      return nullptr;
    }
    if (dot == std::string_view::npos) return p;
    path.remove_prefix(dot + 1);
  }
}

bool glob_match(const std::string& p, const std::string& s) {
  // Iterative wildcard matching with one backtrack point: O(|p|·|s|) worst case.
  std::size_t i = 0, j = 0, star = std::string::npos, mark = 0;
  while (j < s.size()) {
    if (i < p.size() && p[i] != '*' && p[i] == s[j]) {
      ++i;
      ++j;
    } else if (i < p.size() && p[i] == '*') {
      star = i++;
      mark = j;
    } else if (star != std::string::npos) {
      i = star + 1;
      j = ++mark;
    } else {
      return false;
    }
  }
  while (i < p.size() && p[i] == '*') ++i;
  return i == p.size();
}

}  // namespace vtsim
