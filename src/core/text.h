#pragma once
// Reading fields of untrusted text: trimming, and a number that is the whole token or nothing.
// Shared by the readers of traces, access logs, produced-tile CSVs and reports, so that they
// accept and refuse the same spellings.
#include <charconv>
#include <string>
#include <string_view>
#include <system_error>

namespace vtsim::text {

// Spaces and tabs at both ends. A carriage return stays: inside a line it is data to refuse.
inline std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

// The same, and carriage returns at the end too: for readers that split lines themselves and
// take "\r\n" as a line's end (a CR is then whitespace at the end of a line or its last field).
inline std::string_view trim_line(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

// t for a message: its first `max` bytes and "..." when it is longer (a value may be a megabyte
// of junk: quote its start only).
inline std::string shown(std::string_view t, std::size_t max) {
  return t.size() > max ? std::string(t.substr(0, max)) + "..." : std::string(t);
}

// All of t as a T (std::from_chars: no leading '+', no spaces; integers in `base`). False for an
// empty token, characters after the number, or a value outside T's range. Finiteness of a floating
// value ("inf", "nan" parse) is the caller's to check.
template <typename T>
bool parse_whole(std::string_view t, T& v) {
  const auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  return !t.empty() && ec == std::errc() && p == t.data() + t.size();
}
template <typename T>
bool parse_whole(std::string_view t, T& v, int base) {
  const auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), v, base);
  return !t.empty() && ec == std::errc() && p == t.data() + t.size();
}

}  // namespace vtsim::text
