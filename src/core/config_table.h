#pragma once
// One table of config fields serves the TOML file, `--set key=value`, validation and the docs.
// Each field names a dotted key ("clipmap.clipsize"), a member of the config struct, a one-line
// "why", and bounds; loading a file or a --set rejects unknown keys, wrong types and values out of
// range with an InputError naming the key (and the file).
//
// Usage: declare `static const ConfigTable<Cfg>& table()` listing the fields once; then
// `load_toml_file(table, cfg, path)`, `apply_set(table, cfg, "a.b=3")`, `table.describe()`.
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <variant>
#include <vector>

#include "core/error.h"
#include "core/utf8.h"

namespace vtsim {

// A value read from TOML or the command line, before it is checked against a field's type.
using ConfigValue = std::variant<bool, std::int64_t, double, std::string>;

std::string config_value_to_string(const ConfigValue& v);

template <class Cfg>
struct ConfigField {
  std::string key;    // dotted name, e.g. "disk.bandwidth_MBps"
  std::string why;    // one line: what it is for, with its unit
  // Sets the field from a parsed value; throws std::invalid_argument("...") on a type or range
  // problem (the loader adds the key and the source).
  std::function<void(Cfg&, const ConfigValue&)> set;
  std::function<std::string(const Cfg&)> get;  // current value, TOML syntax
};

template <class Cfg>
class ConfigTable {
 public:
  ConfigTable& add(ConfigField<Cfg> f) {
    index_[f.key] = fields_.size();
    fields_.push_back(std::move(f));
    return *this;
  }
  const ConfigField<Cfg>* find(const std::string& key) const {
    auto it = index_.find(key);
    return it == index_.end() ? nullptr : &fields_[it->second];
  }
  const std::vector<ConfigField<Cfg>>& fields() const { return fields_; }

  // Sets one field; `where` names the source for messages ("cfg.toml", "--set").
  void set(Cfg& cfg, const std::string& key, const ConfigValue& v, const std::string& where) const {
    const auto* f = find(key);
    if (!f) {
      // A key may be a megabyte of junk: quote its start only.
      std::string msg = "unknown config key '";
      msg.append(utf8_prefix(key, 100));
      if (key.size() > 100) msg.append("…' (").append(std::to_string(key.size())).append(" characters)");
      else msg.append("'");
      throw InputError(where, msg + suggest(key));
    }
    try {
      f->set(cfg, v);
    } catch (const std::invalid_argument& e) {
      throw InputError(where, "field '" + key + "': " + e.what());
    }
  }

  // A Markdown table of every key: section, key, default (from `cfg`), why.
  std::string markdown(const Cfg& cfg) const {
    std::string out = "| key | default | what it is for |\n|---|---|---|\n";
    for (const auto& f : fields_) {
      std::string why = f.why;
      for (std::size_t p = 0; (p = why.find('|', p)) != std::string::npos; p += 2) why.replace(p, 1, "\\|");
      out += "| `" + f.key + "` | `" + f.get(cfg) + "` | " + why + " |\n";
    }
    return out;
  }

  // "key = value  # why" lines, the effective configuration (for --print-config and reports).
  std::string dump(const Cfg& cfg) const {
    std::string out;
    for (const auto& f : fields_) out += f.key + " = " + f.get(cfg) + "    # " + f.why + "\n";
    return out;
  }

 private:
  std::string suggest(const std::string& key) const;
  std::vector<ConfigField<Cfg>> fields_;
  std::map<std::string, std::size_t> index_;
};

// Field builders. Integers accept TOML integers only; doubles accept integers too.
namespace cfg {

std::int64_t as_int(const ConfigValue& v);
double as_double(const ConfigValue& v);
bool as_bool(const ConfigValue& v);
std::string as_string(const ConfigValue& v);
std::string fmt_double(double d);

template <class Cfg, class T>
ConfigField<Cfg> integer(std::string key, T Cfg::*m, std::int64_t lo, std::int64_t hi, std::string why) {
  return {std::move(key), std::move(why),
          [m, lo, hi](Cfg& c, const ConfigValue& v) {
            const std::int64_t x = as_int(v);
            if (x < lo || x > hi)
              throw std::invalid_argument(std::to_string(x) + " is out of range [" + std::to_string(lo) +
                                          ", " + std::to_string(hi) + "]");
            c.*m = static_cast<T>(x);
          },
          [m](const Cfg& c) { return std::to_string(static_cast<std::int64_t>(c.*m)); }};
}

template <class Cfg>
ConfigField<Cfg> real(std::string key, double Cfg::*m, double lo, double hi, std::string why) {
  return {std::move(key), std::move(why),
          [m, lo, hi](Cfg& c, const ConfigValue& v) {
            const double x = as_double(v);
            if (!(x >= lo && x <= hi))
              throw std::invalid_argument(fmt_double(x) + " is out of range [" + fmt_double(lo) + ", " +
                                          fmt_double(hi) + "]");
            c.*m = x;
          },
          [m](const Cfg& c) { return fmt_double(c.*m); }};
}

template <class Cfg>
ConfigField<Cfg> boolean(std::string key, bool Cfg::*m, std::string why) {
  return {std::move(key), std::move(why), [m](Cfg& c, const ConfigValue& v) { c.*m = as_bool(v); },
          [m](const Cfg& c) { return std::string(c.*m ? "true" : "false"); }};
}

// A string field with a parser/validator; `parse` throws std::invalid_argument on a bad value.
template <class Cfg>
ConfigField<Cfg> text(std::string key, std::string Cfg::*m, std::function<void(const std::string&)> check,
                      std::string why) {
  return {std::move(key), std::move(why),
          [m, check](Cfg& c, const ConfigValue& v) {
            std::string s = as_string(v);
            if (check) check(s);
            c.*m = std::move(s);
          },
          [m](const Cfg& c) { return "\"" + c.*m + "\""; }};
}

}  // namespace cfg

// Parses "key=value" (value: true/false, integer, real, or anything else as a string).
std::pair<std::string, ConfigValue> parse_set_argument(const std::string& arg);

// Reads a TOML file into (dotted key, value, line) triples; tables flatten into dotted keys.
// Arrays are rejected (the config has none). Throws InputError naming the file and line.
struct TomlEntry {
  std::string key;
  ConfigValue value;
  long long line = 0;
};
// A table with no key at all ([name] followed by nothing): no entry, so a caller for whom that
// is a mistake asks for the list.
struct TomlEmptyTable {
  std::string key;
  long long line = 0;
};
std::vector<TomlEntry> read_toml_entries(const std::string& path, std::vector<TomlEmptyTable>* empty_tables = nullptr);

template <class Cfg>
std::string ConfigTable<Cfg>::suggest(const std::string& key) const {
  // Closest key by edit distance, when it is close enough to be a plausible typo.
  auto dist = [](const std::string& a, const std::string& b) {
    std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
    for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
    for (std::size_t i = 1; i <= a.size(); ++i) {
      cur[0] = i;
      for (std::size_t j = 1; j <= b.size(); ++j)
        cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0u : 1u)});
      std::swap(prev, cur);
    }
    return prev[b.size()];
  };
  std::size_t best = 4;
  std::string best_key;
  for (const auto& f : fields_) {
    // The distance is at least the difference in length: a long key costs nothing here.
    const std::size_t diff = key.size() > f.key.size() ? key.size() - f.key.size() : f.key.size() - key.size();
    if (diff >= best) continue;
    const std::size_t d = dist(key, f.key);
    if (d < best) best = d, best_key = f.key;
  }
  return best_key.empty() ? std::string() : " (did you mean '" + best_key + "'?)";
}

template <class Cfg>
void load_toml_file(const ConfigTable<Cfg>& table, Cfg& cfg, const std::string& path) {
  for (const auto& e : read_toml_entries(path)) table.set(cfg, e.key, e.value, at_line(path, e.line));
}

template <class Cfg>
void apply_set(const ConfigTable<Cfg>& table, Cfg& cfg, const std::string& arg) {
  auto [key, value] = parse_set_argument(arg);
  table.set(cfg, key, value, "--set " + arg);
}

}  // namespace vtsim
