#pragma once
// The table of one extension point (streaming systems, scenes, trace formats, disk presets,
// codecs, throttle and residency policies): one entry per name, each with a one-line "why" and
// whatever the point needs to check and make one. Lookups by name, the list of names in --help
// texts and errors, and the tables of docs/config.md all read the same entries, so adding an
// extension is one file and one line in its table and nothing else goes stale.
//
// Entry: any struct with `std::string_view name` and `std::string_view why` members.
// Complexity: find O(entries); entries are few. Thread-safety: immutable once built (the tables
// are function-local statics), so any thread may read them.
#include <algorithm>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "core/text.h"

namespace vtsim {

// Levenshtein distance of two short strings. O(|a|·|b|).
std::size_t edit_distance(std::string_view a, std::string_view b);

// The candidate closest to `word` by edit distance when it is close enough to be a typo: fewer
// than 4 edits, and at most half the length of the shorter of the two ("arc" is 2 edits from
// "lru" but no typo of it); the earlier in `candidates` on a tie; empty otherwise.
std::string closest_name(std::string_view word, const std::vector<std::string_view>& candidates);

template <class Entry>
class Registry {
 public:
  // `what` names an entry in messages: "streaming system", "scene", "trace format", ...
  // Throws std::logic_error for an empty or repeated name (a programming error in the table).
  Registry(std::string what, std::vector<Entry> entries) : what_(std::move(what)), entries_(std::move(entries)) {
    for (std::size_t i = 0; i < entries_.size(); ++i) {
      if (entries_[i].name.empty()) throw std::logic_error(what_ + " registry: an entry without a name");
      for (std::size_t j = 0; j < i; ++j)
        if (entries_[j].name == entries_[i].name)
          throw std::logic_error(what_ + " registry: '" + std::string(entries_[i].name) + "' twice");
    }
  }

  const std::string& what() const { return what_; }
  const std::vector<Entry>& entries() const { return entries_; }

  // nullptr when no entry has that name.
  const Entry* find(std::string_view name) const {
    for (const Entry& e : entries_)
      if (e.name == name) return &e;
    return nullptr;
  }

  // The entry of that name; throws std::invalid_argument("unknown <what> 'x' (one of: a, b, c;
  // did you mean 'b'?)") otherwise. Callers add the field or option it came from.
  const Entry& at(std::string_view name) const {
    if (const Entry* e = find(name)) return *e;
    throw std::invalid_argument(unknown(name));
  }

  std::string unknown(std::string_view name) const {
    std::vector<std::string_view> names;
    for (const Entry& e : entries_) names.push_back(e.name);
    const std::string shown = text::shown(name, 100);
    std::string msg = "unknown " + what_ + " '" + shown + "' (one of: " + this->names();
    const std::string close = closest_name(name, names);
    if (!close.empty()) msg += "; did you mean '" + close + "'?";
    return msg + ")";
  }

  // "a, b, c" (or joined by `sep`), in table order.
  std::string names(std::string_view sep = ", ") const {
    std::string out;
    for (const Entry& e : entries_) {
      if (!out.empty()) out += sep;
      out += e.name;
    }
    return out;
  }

  // A Markdown table of the entries: | name | why |.
  std::string markdown(std::string_view name_header = "name") const {
    std::string out = "| " + std::string(name_header) + " | what it is for |\n|---|---|\n";
    for (const Entry& e : entries_) {
      std::string why(e.why);
      for (std::size_t p = 0; (p = why.find('|', p)) != std::string::npos; p += 2) why.replace(p, 1, "\\|");
      out += "| `" + std::string(e.name) + "` | " + why + " |\n";
    }
    return out;
  }

 private:
  std::string what_;
  std::vector<Entry> entries_;
};

}  // namespace vtsim
