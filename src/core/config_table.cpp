#include "core/config_table.h"
#include "core/input_file.h"

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>
#include <toml++/toml.h>

#include "core/toml_text.h"

namespace vtsim {

std::string config_value_to_string(const ConfigValue& v) {
  return std::visit(
      [](const auto& x) -> std::string {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, bool>) return x ? "true" : "false";
        else if constexpr (std::is_same_v<T, std::string>) return "\"" + x + "\"";
        else if constexpr (std::is_same_v<T, double>) return cfg::fmt_double(x);
        else return std::to_string(x);
      },
      v);
}

namespace cfg {

std::int64_t as_int(const ConfigValue& v) {
  if (const auto* i = std::get_if<std::int64_t>(&v)) return *i;
  if (const auto* d = std::get_if<double>(&v)) {
    if (std::isfinite(*d) && *d == std::floor(*d) && std::fabs(*d) < 9.0e18) return static_cast<std::int64_t>(*d);
  }
  throw std::invalid_argument("expected an integer, got " + config_value_to_string(v));
}

double as_double(const ConfigValue& v) {
  if (const auto* d = std::get_if<double>(&v)) {
    if (!std::isfinite(*d)) throw std::invalid_argument("expected a finite number, got " + fmt_double(*d));
    return *d;
  }
  if (const auto* i = std::get_if<std::int64_t>(&v)) return static_cast<double>(*i);
  throw std::invalid_argument("expected a number, got " + config_value_to_string(v));
}

bool as_bool(const ConfigValue& v) {
  if (const auto* b = std::get_if<bool>(&v)) return *b;
  throw std::invalid_argument("expected true or false, got " + config_value_to_string(v));
}

std::string as_string(const ConfigValue& v) {
  if (const auto* s = std::get_if<std::string>(&v)) return *s;
  // Numbers are accepted where a string is expected (e.g. --set name=5): use their text.
  return std::visit(
      [](const auto& x) -> std::string {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, bool>) return x ? "true" : "false";
        else if constexpr (std::is_same_v<T, std::string>) return x;
        else if constexpr (std::is_same_v<T, double>) return fmt_double(x);
        else return std::to_string(x);
      },
      v);
}

std::string fmt_double(double d) { return fmt::format("{}", d); }

}  // namespace cfg

std::pair<std::string, ConfigValue> parse_set_argument(const std::string& arg) {
  const auto eq = arg.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError("--set " + arg, "expected key=value (e.g. --set upload.tiles_per_frame=8)");
  std::string key = arg.substr(0, eq), text = arg.substr(eq + 1);
  auto trim = [](std::string& s) {
    const auto b = s.find_first_not_of(" \t"), e = s.find_last_not_of(" \t");
    s = b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
  };
  trim(key);
  trim(text);
  if (text == "true") return {key, true};
  if (text == "false") return {key, false};
  if (text.size() >= 2 && text.front() == '"' && text.back() == '"') return {key, text.substr(1, text.size() - 2)};
  // Integer?
  {
    std::size_t pos = 0;
    try {
      const long long i = std::stoll(text, &pos, 10);
      if (pos == text.size()) return {key, static_cast<std::int64_t>(i)};
    } catch (const std::exception&) {
    }
  }
  // Real? strtod, not stod: out of range is still a number (an underflow its subnormal or zero, an
  // overflow infinity), which the field's bounds then reject with its range.
  if (!text.empty()) {  // (trimmed)
    char* end = nullptr;
    const double d = std::strtod(text.c_str(), &end);
    if (end == text.c_str() + text.size()) return {key, d};
  }
  return {key, text};
}

namespace {

// Each dot of a dotted key or table name opens a table one level deeper, and so does each inline
// table or array. toml++ builds dotted tables iteratively but destroys them recursively, and
// flatten() recurses, so a key of a million dots (a 16 MiB file allows eight) overflows the stack.
// The nesting is counted in the text before it is parsed: the dots of a key outside quoted strings
// plus the levels of the inline tables and arrays around it (with their keys' dots); a table
// header counts alone. Values and comments are skipped. vtsim's keys have at most two dots.
constexpr int kMaxNesting = 16;

}  // namespace

void check_toml_nesting(const std::string& text, const std::string& path) {
  enum class Mode { key, value };
  Mode mode = Mode::key;
  std::vector<char> open;   // '{' inline tables, '[' arrays (not table headers)
  std::vector<int> saved;   // `outer` before each of them opened
  int outer = 0;            // levels around the current key or value
  int dots = 0;             // dots of the current key
  int key_dots = 0;         // dots of the key whose value is being read
  long long line = 1;
  const auto too_deep = [&] {
    throw InputError(at_line(path, line), "a key or table name nested more than " + std::to_string(kMaxNesting) +
                                              " levels deep (dotted keys, inline tables, arrays)");
  };
  const std::size_t n = text.size();
  for (std::size_t i = 0; i < n; ++i) {
    const char c = text[i];
    if (c == '\n') {
      ++line;
      if (open.empty()) mode = Mode::key, dots = 0;
    } else if (c == '#') {
      while (i + 1 < n && text[i + 1] != '\n') ++i;
    } else if (c == '"' || c == '\'') {
      // A string: basic ("..." with escapes) or literal ('...'), single- or multi-line (tripled).
      const bool triple = i + 2 < n && text[i + 1] == c && text[i + 2] == c;
      i += triple ? 3 : 1;
      for (; i < n; ++i) {
        if (text[i] == '\n') ++line;
        if (c == '"' && text[i] == '\\') {
          if (i + 1 < n && text[i + 1] == '\n') ++line;
          ++i;
        } else if (text[i] == c && (!triple || (i + 2 < n && text[i + 1] == c && text[i + 2] == c))) {
          if (triple) {
            i += 2;
            while (i + 1 < n && text[i + 1] == c) ++i;  // up to two quotes may end the content
          }
          break;
        } else if (!triple && text[i] == '\n') {
          break;  // unterminated: the parser reports it
        }
      }
    } else if (!open.empty() && ((c == '}' && open.back() == '{') || (c == ']' && open.back() == '[' && mode == Mode::value))) {
      open.pop_back();  // also an empty inline table, closed in key mode
      outer = saved.back();
      saved.pop_back();
      mode = Mode::value;
    } else if (mode == Mode::key) {
      if (c == '.' && outer + ++dots > kMaxNesting) too_deep();
      if (c == '=') mode = Mode::value, key_dots = dots, dots = 0;
      if (c == ']' && open.empty()) dots = 0;  // the end of a table header
    } else if (c == '{' || c == '[') {
      saved.push_back(outer);
      outer += 1 + key_dots;
      key_dots = 0;
      if (outer > kMaxNesting) too_deep();
      open.push_back(c);
      if (c == '{') mode = Mode::key, dots = 0;
    } else if (c == ',' && !open.empty()) {
      key_dots = 0;
      if (open.back() == '{') mode = Mode::key, dots = 0;
    }
  }
}

namespace {

// prefix: the enclosing table's dotted key, nullptr at the root (a table may be named "").
void flatten(const toml::table& t, const std::string* prefix, const std::string& path,
             std::vector<TomlEntry>& out, std::vector<TomlEmptyTable>* empty_tables) {
  for (const auto& [k, node] : t) {
    const std::string key = prefix ? *prefix + "." + std::string(k.str()) : std::string(k.str());
    const long long line = static_cast<long long>(node.source().begin.line);
    if (const auto* sub = node.as_table()) {
      if (sub->empty() && empty_tables) empty_tables->push_back({key, line});
      flatten(*sub, &key, path, out, empty_tables);
    } else if (const auto* i = node.as_integer()) {
      out.push_back({key, static_cast<std::int64_t>(i->get()), line});
    } else if (const auto* d = node.as_floating_point()) {
      out.push_back({key, d->get(), line});
    } else if (const auto* b = node.as_boolean()) {
      out.push_back({key, b->get(), line});
    } else if (const auto* s = node.as_string()) {
      // A path with a NUL would open the file named by its first part.
      if (s->get().find('\0') != std::string::npos)
        throw InputError(at_line(path, line), "field '" + key + "': a string with a NUL character");
      out.push_back({key, s->get(), line});
    } else {
      throw InputError(at_line(path, line), "field '" + key + "': unsupported value type (expected a number, "
                                            "boolean or string)");
    }
  }
}

}  // namespace

toml::table parse_toml_text(const std::string& text, const std::string& path) {
  check_toml_nesting(text, path);
  try {
    return toml::parse(text, path);
  } catch (const toml::parse_error& e) {
    throw InputError(at_line(path, static_cast<long long>(e.source().begin.line)),
                     std::string("TOML syntax error: ") + std::string(e.description()));
  }
}

std::vector<TomlEntry> read_toml_entries(const std::string& path, std::vector<TomlEmptyTable>* empty_tables) {
  const std::string text = read_regular_file(path, 16u << 20, "not a vtsim TOML file");
  const toml::table tbl = parse_toml_text(text, path);
  std::vector<TomlEntry> out;
  flatten(tbl, nullptr, path, out, empty_tables);
  return out;
}

}  // namespace vtsim
