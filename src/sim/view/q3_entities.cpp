#include "sim/view/q3_entities.h"

#include <fmt/core.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.h"
#include "core/input_file.h"
#include "core/text.h"

namespace vtsim {

namespace {

// Little-endian unsigned of n bytes at s[at]; the caller has checked the bounds.
std::uint64_t q3e_le(std::string_view s, std::size_t at, int n) {
  std::uint64_t v = 0;
  for (int k = n - 1; k >= 0; --k) v = (v << 8) | static_cast<unsigned char>(s[at + static_cast<std::size_t>(k)]);
  return v;
}

// Q3 BSP header (q3map qfiles.h): "IBSP", int32 version 46, 17 lumps of (int32 offset, int32 length).
constexpr int kQ3Version = 46;
constexpr std::size_t kQ3Lumps = 17, kQ3HeaderBytes = 8 + kQ3Lumps * 8;

bool q3e_is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v'; }

double q3e_number(std::string_view s, const std::string& where, const std::string& key) {
  double x = 0.0;
  if (!text::parse_whole(s, x) || !std::isfinite(x))
    throw InputError(where, fmt::format("\"{}\" \"{}\": not a finite number", key, s));
  return x;
}

glm::dvec3 q3e_origin(std::string_view s, const std::string& where) {
  double v[3] = {0, 0, 0};
  std::size_t b = 0;
  for (int k = 0; k < 3; ++k) {
    while (b < s.size() && q3e_is_space(s[b])) ++b;
    std::size_t e = b;
    while (e < s.size() && !q3e_is_space(s[e])) ++e;
    if (b == e) throw InputError(where, fmt::format("\"origin\" \"{}\": not three numbers", s));
    v[k] = q3e_number(s.substr(b, e - b), where, "origin");
    b = e;
  }
  while (b < s.size() && q3e_is_space(s[b])) ++b;
  if (b != s.size()) throw InputError(where, fmt::format("\"origin\" \"{}\": not three numbers", s));
  return {v[0], v[1], v[2]};
}

// A stored (uncompressed) maps/*.bsp of a zip, the only one it holds (PKWARE APPNOTE 4.3: end of
// central directory, central directory headers, local file headers).
std::string_view q3e_pk3_bsp(std::string_view z, const std::string& name) {
  const auto bad = [&](const std::string& what) { return InputError(name, "pk3 (zip): " + what); };
  if (z.size() < 22) throw bad("too short for a zip");
  std::size_t eocd = std::string_view::npos;
  const std::size_t lowest = z.size() > 22 + 65535 ? z.size() - 22 - 65535 : 0;
  for (std::size_t at = z.size() - 22 + 1; at-- > lowest;)
    if (q3e_le(z, at, 4) == 0x06054b50) {
      eocd = at;
      break;
    }
  if (eocd == std::string_view::npos) throw bad("no end of central directory record");
  const std::uint64_t entries = q3e_le(z, eocd + 10, 2), cd_off = q3e_le(z, eocd + 16, 4);
  std::uint64_t at = cd_off;
  std::string found;
  std::uint64_t method = 0, csize = 0, usize = 0, local = 0;
  int bsps = 0;
  for (std::uint64_t i = 0; i < entries; ++i) {
    if (at + 46 > z.size() || q3e_le(z, at, 4) != 0x02014b50)
      throw bad(fmt::format("central directory entry {} is outside the file or damaged", i));
    const std::uint64_t n = q3e_le(z, at + 28, 2), extra = q3e_le(z, at + 30, 2), comment = q3e_le(z, at + 32, 2);
    if (at + 46 + n > z.size()) throw bad(fmt::format("central directory entry {}: name outside the file", i));
    const std::string_view fname = z.substr(at + 46, n);
    if (fname.size() > 9 && fname.substr(0, 5) == "maps/" && fname.substr(fname.size() - 4) == ".bsp") {
      ++bsps;
      found = std::string(fname);
      method = q3e_le(z, at + 10, 2);
      csize = q3e_le(z, at + 20, 4);
      usize = q3e_le(z, at + 24, 4);
      local = q3e_le(z, at + 42, 4);
    }
    at += 46 + n + extra + comment;
  }
  if (bsps != 1)
    throw bad(fmt::format("holds {} maps/*.bsp entries; a level pk3 holds exactly one "
                          "(scripts/fetch_levels.sh writes them)", bsps));
  if (method != 0 || csize != usize)
    throw bad(fmt::format("{} is compressed (method {}); vtsim reads stored entries only: extract the .bsp, "
                          "or write the pk3 with scripts/fetch_levels.sh", found, method));
  if (local + 30 > z.size() || q3e_le(z, local, 4) != 0x04034b50)
    throw bad(fmt::format("{}: local header outside the file or damaged", found));
  const std::uint64_t data = local + 30 + q3e_le(z, local + 26, 2) + q3e_le(z, local + 28, 2);
  if (data > z.size() || usize > z.size() - data) throw bad(fmt::format("{}: data outside the file", found));
  return z.substr(data, usize);
}

}  // namespace

bool is_q3_spawn(const Q3Entity& e) {
  const std::string& c = e.classname;
  return c == "info_player_deathmatch" || c == "info_player_start" || c == "team_CTF_redspawn" ||
         c == "team_CTF_bluespawn" || c == "team_CTF_redplayer" || c == "team_CTF_blueplayer";
}

bool is_q3_item(const Q3Entity& e) {
  const std::string_view c = e.classname;
  return c.starts_with("weapon_") || c.starts_with("item_") || c.starts_with("ammo_") || c.starts_with("holdable_");
}

std::vector<Q3Entity> parse_q3_entity_text(std::string_view text, const std::string& name, const Q3Limits& limits) {
  if (const std::size_t nul = text.find('\0'); nul != std::string_view::npos) text = text.substr(0, nul);
  if (text.size() > limits.max_entity_bytes)
    throw InputError(name, fmt::format("entity text of {} bytes, larger than the limit {}", text.size(),
                                       limits.max_entity_bytes));
  std::vector<Q3Entity> out;
  std::size_t i = 0;
  long long line = 1;
  const auto where = [&] { return fmt::format("{}: entities line {}", name, line); };
  // The next token: a quoted string (no escapes, as the engine's COM_Parse), '{', '}', or a bare
  // word; empty optional-like result at the end of the text.
  const auto next = [&](std::string_view& tok, bool& quoted) -> bool {
    for (;;) {
      while (i < text.size() && q3e_is_space(text[i])) line += text[i++] == '\n';
      if (i + 1 < text.size() && text[i] == '/' && text[i + 1] == '/') {  // a comment to the end of the line
        while (i < text.size() && text[i] != '\n') ++i;
        continue;
      }
      break;
    }
    if (i >= text.size()) return false;
    quoted = text[i] == '"';
    if (quoted) {
      const std::size_t e = text.find('"', i + 1);
      if (e == std::string_view::npos) throw InputError(where(), "unterminated quoted string");
      tok = text.substr(i + 1, e - i - 1);
      for (char c : tok) line += c == '\n';
      i = e + 1;
      return true;
    }
    if (text[i] == '{' || text[i] == '}') {
      tok = text.substr(i++, 1);
      return true;
    }
    const std::size_t b = i;
    while (i < text.size() && !q3e_is_space(text[i]) && text[i] != '"' && text[i] != '{' && text[i] != '}') ++i;
    tok = text.substr(b, i - b);
    return true;
  };
  std::string_view tok;
  bool quoted = false;
  while (next(tok, quoted)) {
    if (quoted || tok != "{") throw InputError(where(), fmt::format("expected '{{' to open an entity, found '{}'", tok));
    if (out.size() >= limits.max_entities)
      throw InputError(where(), fmt::format("more than {} entities", limits.max_entities));
    Q3Entity e;
    for (;;) {
      if (!next(tok, quoted)) throw InputError(where(), "the entity opened is not closed with '}' before the end");
      if (!quoted && tok == "}") break;
      if (!quoted && tok == "{") throw InputError(where(), "'{' inside an entity");
      const std::string key(tok);
      const long long key_line = line;
      if (!next(tok, quoted) || (!quoted && (tok == "}" || tok == "{")))
        throw InputError(where(), fmt::format("key \"{}\" has no value", key));
      const std::string at = fmt::format("{}: entities line {}", name, key_line);
      if (key == "classname") e.classname = std::string(tok);
      else if (key == "origin") e.origin = q3e_origin(tok, at);
      else if (key == "angle") e.angle_deg = q3e_number(tok, at, key);
      e.keys.emplace_back(key, std::string(tok));
    }
    out.push_back(std::move(e));
  }
  return out;
}

std::vector<Q3Entity> parse_q3_bsp(std::string_view b, const std::string& name, const Q3Limits& limits) {
  if (b.size() < kQ3HeaderBytes)
    throw InputError(name, fmt::format("{} bytes, shorter than a Quake 3 BSP header ({} bytes)", b.size(), kQ3HeaderBytes));
  if (b.substr(0, 4) != "IBSP")
    throw InputError(name, "not a Quake 3 BSP: the file does not start with \"IBSP\"");
  const auto version = static_cast<std::int32_t>(q3e_le(b, 4, 4));
  if (version != kQ3Version)
    throw InputError(name, fmt::format("BSP version {}, not {} (Quake 3 / OpenArena)", version, kQ3Version));
  const auto off = static_cast<std::int32_t>(q3e_le(b, 8, 4)), len = static_cast<std::int32_t>(q3e_le(b, 12, 4));
  if (off < 0 || len < 0 || static_cast<std::uint64_t>(off) + static_cast<std::uint64_t>(len) > b.size())
    throw InputError(name, fmt::format("entity lump (offset {}, length {}) is outside the file of {} bytes", off, len,
                                       b.size()));
  if (static_cast<std::uint64_t>(len) > limits.max_entity_bytes)
    throw InputError(name, fmt::format("entity lump of {} bytes, larger than the limit {}", len, limits.max_entity_bytes));
  return parse_q3_entity_text(b.substr(static_cast<std::size_t>(off), static_cast<std::size_t>(len)), name, limits);
}

std::vector<Q3Entity> read_q3_entities(const std::string& path, const Q3Limits& limits) {
  const std::string bytes = read_regular_file(path, limits.max_file_bytes, "not a level this reader accepts");
  const bool zip = bytes.size() >= 4 && bytes.compare(0, 4, "PK\x03\x04") == 0;
  return parse_q3_bsp(zip ? q3e_pk3_bsp(bytes, path) : std::string_view(bytes), path, limits);
}

}  // namespace vtsim
