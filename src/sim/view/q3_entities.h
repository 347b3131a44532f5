#pragma once
// The entities of a Quake 3 level (BSP version 46, "IBSP"; the format as id Software's
// q3map/qfiles.h defines it): lump 0 of the file is a text of blocks
//   { "classname" "info_player_deathmatch" "origin" "280 1416 -120" "angle" "180" }
// Spawn points and items give the waypoints of a walk through the level (level_walk.h,
// docs/levels.md). Quake units (1 unit = 1 inch = 0.0254 m), z up, as the level's geometry.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

namespace vtsim {

struct Q3Entity {
  std::string classname;                                   // "" when the block names none
  std::optional<glm::dvec3> origin;                        // "origin" "x y z", Quake units
  double angle_deg = 0.0;                                  // "angle", counter-clockwise from +x; 0 if absent
  std::vector<std::pair<std::string, std::string>> keys;   // every key/value pair, in file order
};

// Limits for untrusted levels (InputError beyond them).
struct Q3Limits {
  std::uint64_t max_file_bytes = std::uint64_t{1} << 30;   // 1 GiB: the largest shipped levels are ~10 MB
  std::uint64_t max_entity_bytes = 16u << 20;              // entity lump: shipped ones are < 100 kB
  std::uint64_t max_entities = 1u << 16;                   // the Q3 engine's own limit is 1024 (MAX_GENTITIES)
};

// Reads the entity lump of `path`: a .bsp, or a .pk3 (zip) holding exactly one maps/*.bsp stored
// uncompressed, as scripts/fetch_levels.sh writes them (a deflated entry is refused, naming the
// script: vtsim links no zlib). Throws InputError(path, ...) for an unreadable file, a bad magic or
// version, a lump outside the file, a lump or file over the limits, or malformed entity text
// (with the line: "path: entities line 12: ...").
std::vector<Q3Entity> read_q3_entities(const std::string& path, const Q3Limits& limits = {});
// The same on the bytes of a .bsp in memory; `name` is used in error messages.
std::vector<Q3Entity> parse_q3_bsp(std::string_view bytes, const std::string& name, const Q3Limits& limits = {});
// The entity text alone (lump 0's bytes; a trailing NUL ends it).
std::vector<Q3Entity> parse_q3_entity_text(std::string_view text, const std::string& name,
                                           const Q3Limits& limits = {});

// Spawn points: info_player_deathmatch, info_player_start, team_CTF_{red,blue}{spawn,player}.
bool is_q3_spawn(const Q3Entity& e);
// Pick-ups: weapon_*, item_*, ammo_*, holdable_*.
bool is_q3_item(const Q3Entity& e);

}  // namespace vtsim
