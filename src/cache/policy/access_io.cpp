#include "cache/policy/access_io.h"

#include <fmt/format.h>

#include <stdexcept>
#include <string>
#include <string_view>

#include "cache/policy/i_replacement.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/input_file.h"
#include "core/text.h"

namespace vtsim {

namespace {

// Access sizes above 2^40 are refused: miss-ratio curves sum them (cache/policy/mrc.h).
constexpr std::uint64_t kAccessMaxSize = std::uint64_t{1} << 40;

// The next whitespace-separated token of s (consumed), empty at the end.
std::string_view access_token(std::string_view& s) {
  s = text::trim_line(s);
  std::size_t e = 0;
  while (e < s.size() && s[e] != ' ' && s[e] != '\t') ++e;
  const std::string_view t = s.substr(0, e);
  s.remove_prefix(e);
  return t;
}

bool access_number(std::string_view t, std::uint64_t& v) {
  int base = 10;
  if (t.size() > 2 && t[0] == '0' && (t[1] == 'x' || t[1] == 'X')) {
    t.remove_prefix(2);
    base = 16;
  }
  return text::parse_whole(t, v, base);
}

std::string access_shown(std::string_view t) {
  return text::shown(t, 40);
}

}  // namespace

AccessLog parse_accesses(std::string_view text, const std::string& name) {
  AccessLog log;
  long long line_no = 0;
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    std::string_view line = text.substr(0, nl);
    text.remove_prefix(nl == std::string_view::npos ? text.size() : nl + 1);
    ++line_no;
    if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
    const std::string_view key_t = access_token(line);
    if (key_t.empty()) continue;
    if (key_t == "frame") {
      if (!access_token(line).empty()) throw InputError(at_line(name, line_no), "'frame' takes nothing after it");
      log.frame_start.push_back(log.accesses.size());
      continue;
    }
    Access a;
    if (!access_number(key_t, a.key))
      throw InputError(at_line(name, line_no),
                       fmt::format("key '{}' is not a decimal or 0x-hex integer below 2^64", access_shown(key_t)));
    if (a.key == kNoKey) throw InputError(at_line(name, line_no), "key 0xffffffffffffffff is reserved (never a key)");
    const std::string_view size_tok = access_token(line);
    if (!size_tok.empty()) {
      std::uint64_t s = 0;
      if (!text::parse_whole(size_tok, s) || s < 1 || s > kAccessMaxSize)
        throw InputError(at_line(name, line_no),
                         fmt::format("size '{}' is not a decimal integer in [1, 2^40]", access_shown(size_tok)));
      a.size = s;
    }
    if (const std::string_view extra = access_token(line); !extra.empty())
      throw InputError(at_line(name, line_no),
                       fmt::format("'{}' after the size: expected 'key [size]'", access_shown(extra)));
    log.accesses.push_back(a);
  }
  return log;
}

AccessLog read_access_file(const std::string& path) {
  const std::string text =
      read_regular_file(path, kMaxAccessFileBytes, "split the sequence, or sample it (vtsim mrc --shards)");
  AccessLog log = parse_accesses(text, path);
  if (log.accesses.empty())  // a curve of nothing is all zeros: an empty input is a mistake, not a result
    throw InputError(path, text.empty() ? "is empty: an access file holds one access per line ('key [size]')"
                                        : "holds no access (only comments, blank or 'frame' lines)");
  return log;
}

std::string format_accesses(const AccessLog& log) {
  std::string out =
      "# vtsim accesses: one access per line, key (0x-hex) and size; 'frame' starts a frame (docs/cache.md)\n";
  std::size_t f = 0;
  for (std::size_t i = 0; i <= log.accesses.size(); ++i) {
    for (; f < log.frame_start.size() && log.frame_start[f] == i; ++f) out += "frame\n";
    if (i == log.accesses.size()) break;
    const Access& a = log.accesses[i];
    if (a.key == kNoKey || a.size < 1 || a.size > kAccessMaxSize)
      throw std::invalid_argument(fmt::format("format_accesses: access {}: key ~0 or a size outside [1, 2^40]", i));
    out += fmt::format("{:#x} {}\n", a.key, a.size);
  }
  if (f != log.frame_start.size()) throw std::invalid_argument("format_accesses: frame_start beyond the accesses or decreasing");
  return out;
}

void write_access_file(const std::string& path, const AccessLog& log) {
  write_file_atomic(path, format_accesses(log));
}

}  // namespace vtsim
