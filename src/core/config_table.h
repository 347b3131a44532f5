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
#include <type_traits>
#include <utility>
#include <string>
#include <variant>
#include <vector>

#include "core/error.h"
#include "core/registry.h"
#include "core/utf8.h"

namespace vtsim {

// A value read from TOML or the command line, before it is checked against a field's type.
using ConfigValue = std::variant<bool, std::int64_t, double, std::string>;

std::string config_value_to_string(const ConfigValue& v);

// The JSON type of a field's value (the effective config in a summary, docs/metrics.md).
enum class ConfigType { integer, real, boolean, text };

template <class Cfg>
struct ConfigField {
  std::string key;    // dotted name, e.g. "disk.bandwidth_MBps"
  std::string why;    // one line: what it is for, with its unit
  // Sets the field from a parsed value; throws std::invalid_argument("...") on a type or range
  // problem (the loader adds the key and the source).
  std::function<void(Cfg&, const ConfigValue&)> set;
  std::function<std::string(const Cfg&)> get;  // current value, TOML syntax
  ConfigType type = ConfigType::text;
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

// Where a field lives in the config struct: a data member pointer (&Cfg::fps) or a path of them
// into nested sections (at(&Cfg::throttle, &ThrottleParams::deadline_ms)).
template <class First, class... Rest>
struct MemberPath {
  First first;
  MemberPath<Rest...> rest;
  template <class T>
  decltype(auto) operator()(T& obj) const {
    return rest(obj.*first);
  }
};
template <class Last>
struct MemberPath<Last> {
  Last last;
  template <class T>
  decltype(auto) operator()(T& obj) const {
    return (obj.*last);
  }
};
template <class First, class... Rest>
MemberPath<First, Rest...> at(First first, Rest... rest) {
  if constexpr (sizeof...(Rest) == 0) return MemberPath<First>{first};
  else return MemberPath<First, Rest...>{first, at(rest...)};  // each level braced (clang's -Wmissing-braces)
}

// The member `ref` designates in `c` (a reference, const when c is).
template <class Cfg, class Ref>
decltype(auto) member(Cfg& c, const Ref& ref) {
  if constexpr (std::is_member_object_pointer_v<Ref>) return (c.*ref);
  else return ref(c);
}
template <class Cfg, class Ref>
using MemberType = std::remove_cvref_t<decltype(member(std::declval<Cfg&>(), std::declval<const Ref&>()))>;

template <class Cfg, class Ref>
ConfigField<Cfg> integer(std::string key, Ref m, std::int64_t lo, std::int64_t hi, std::string why) {
  using T = MemberType<Cfg, Ref>;
  return {std::move(key), std::move(why),
          [m, lo, hi](Cfg& c, const ConfigValue& v) {
            const std::int64_t x = as_int(v);
            if (x < lo || x > hi)
              throw std::invalid_argument(std::to_string(x) + " is out of range [" + std::to_string(lo) +
                                          ", " + std::to_string(hi) + "]");
            member(c, m) = static_cast<T>(x);
          },
          [m](const Cfg& c) { return std::to_string(static_cast<std::int64_t>(member(c, m))); }, ConfigType::integer};
}

template <class Cfg, class Ref>
ConfigField<Cfg> real(std::string key, Ref m, double lo, double hi, std::string why) {
  static_assert(std::is_same_v<MemberType<Cfg, Ref>, double>, "cfg::real binds a double");
  return {std::move(key), std::move(why),
          [m, lo, hi](Cfg& c, const ConfigValue& v) {
            const double x = as_double(v);
            if (!(x >= lo && x <= hi))
              throw std::invalid_argument(fmt_double(x) + " is out of range [" + fmt_double(lo) + ", " +
                                          fmt_double(hi) + "]");
            member(c, m) = x;
          },
          [m](const Cfg& c) { return fmt_double(member(c, m)); }, ConfigType::real};
}

template <class Cfg, class Ref>
ConfigField<Cfg> boolean(std::string key, Ref m, std::string why) {
  static_assert(std::is_same_v<MemberType<Cfg, Ref>, bool>, "cfg::boolean binds a bool");
  return {std::move(key), std::move(why), [m](Cfg& c, const ConfigValue& v) { member(c, m) = as_bool(v); },
          [m](const Cfg& c) { return std::string(member(c, m) ? "true" : "false"); }, ConfigType::boolean};
}

// A string field with a validator; `check` throws std::invalid_argument on a bad value.
template <class Cfg, class Ref>
ConfigField<Cfg> text(std::string key, Ref m, std::function<void(const std::string&)> check, std::string why) {
  static_assert(std::is_same_v<MemberType<Cfg, Ref>, std::string>, "cfg::text binds a std::string");
  return {std::move(key), std::move(why),
          [m, check](Cfg& c, const ConfigValue& v) {
            std::string s = as_string(v);
            if (check) check(s);
            member(c, m) = std::move(s);
          },
          [m](const Cfg& c) { return "\"" + member(c, m) + "\""; }, ConfigType::text};
}

// A string field naming an entry of a registry (core/registry.h): an unknown name is refused with
// the registry's list and "did you mean"; the why ends with the names, from the same table.
template <class Cfg, class Ref, class Entry>
ConfigField<Cfg> choice(std::string key, Ref m, const Registry<Entry>& registry, std::string why) {
  return text<Cfg>(std::move(key), m, [&registry](const std::string& v) { registry.at(v); },
                   std::move(why) + ": " + registry.names(" | "));
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
  std::vector<std::string_view> keys;
  for (const auto& f : fields_) keys.push_back(f.key);
  const std::string best = closest_name(key, keys);
  return best.empty() ? std::string() : " (did you mean '" + best + "'?)";
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
