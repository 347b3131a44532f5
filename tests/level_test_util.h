#pragma once
// Small levels made in the tests (no game data needed): Quake 3 BSP bytes holding only an entity
// lump, a zip (pk3) around them, and a two-room level as a triangle mesh.
#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "sim/view/mesh.h"

namespace vtsim::test {

inline void put_le(std::string& s, std::uint64_t v, int n) {
  for (int k = 0; k < n; ++k) s.push_back(static_cast<char>((v >> (8 * k)) & 0xFF));
}

// A Quake 3 BSP (magic, version, 17 lumps) whose entity lump (lump 0) holds `entities`; the other
// lumps are empty.
inline std::string make_q3_bsp(const std::string& entities, int version = 46, const char* magic = "IBSP") {
  std::string s(magic, 4);
  put_le(s, static_cast<std::uint32_t>(version), 4);
  const std::uint32_t header = 8 + 17 * 8;
  put_le(s, header, 4);
  put_le(s, entities.size(), 4);
  for (int k = 1; k < 17; ++k) {
    put_le(s, header, 4);
    put_le(s, 0, 4);
  }
  return s + entities;
}

// A zip of one entry (name, data), stored (method 0) or marked with another method; no CRC (the
// reader does not check it).
inline std::string make_zip(const std::string& name, const std::string& data, int method = 0) {
  std::string z;
  put_le(z, 0x04034b50, 4);
  put_le(z, 20, 2);
  put_le(z, 0, 2);
  put_le(z, static_cast<std::uint64_t>(method), 2);
  put_le(z, 0, 4);  // time, date
  put_le(z, 0, 4);  // crc
  put_le(z, data.size(), 4);
  put_le(z, data.size(), 4);
  put_le(z, name.size(), 2);
  put_le(z, 0, 2);
  z += name + data;
  const std::size_t cd = z.size();
  put_le(z, 0x02014b50, 4);
  put_le(z, 20, 2);
  put_le(z, 20, 2);
  put_le(z, 0, 2);
  put_le(z, static_cast<std::uint64_t>(method), 2);
  put_le(z, 0, 4);
  put_le(z, 0, 4);
  put_le(z, data.size(), 4);
  put_le(z, data.size(), 4);
  put_le(z, name.size(), 2);
  put_le(z, 0, 2);
  put_le(z, 0, 2);
  put_le(z, 0, 2);
  put_le(z, 0, 2);
  put_le(z, 0, 4);
  put_le(z, 0, 4);  // local header offset
  z += name;
  const std::size_t cd_size = z.size() - cd;
  put_le(z, 0x06054b50, 4);
  put_le(z, 0, 4);
  put_le(z, 1, 2);
  put_le(z, 1, 2);
  put_le(z, cd_size, 4);
  put_le(z, cd, 4);
  put_le(z, 0, 2);
  return z;
}

inline void level_add_quad(Mesh& m, glm::dvec3 a, glm::dvec3 b, glm::dvec3 c, glm::dvec3 d) {
  const auto base = static_cast<std::uint32_t>(m.positions.size());
  m.positions.insert(m.positions.end(), {a, b, c, d});
  m.tris.push_back({{base, base + 1, base + 2}, {-1, -1, -1}});
  m.tris.push_back({{base, base + 2, base + 3}, {-1, -1, -1}});
}

inline void level_add_box(Mesh& m, glm::dvec3 lo, glm::dvec3 hi) {
  const auto p = [&](int x, int y, int z) { return glm::dvec3(x ? hi.x : lo.x, y ? hi.y : lo.y, z ? hi.z : lo.z); };
  level_add_quad(m, p(0, 0, 0), p(0, 1, 0), p(1, 1, 0), p(1, 0, 0));  // bottom
  level_add_quad(m, p(0, 0, 1), p(1, 0, 1), p(1, 1, 1), p(0, 1, 1));  // top
  level_add_quad(m, p(0, 0, 0), p(1, 0, 0), p(1, 0, 1), p(0, 0, 1));  // -y
  level_add_quad(m, p(0, 1, 0), p(0, 1, 1), p(1, 1, 1), p(1, 1, 0));  // +y
  level_add_quad(m, p(0, 0, 0), p(0, 0, 1), p(0, 1, 1), p(0, 1, 0));  // -x
  level_add_quad(m, p(1, 0, 0), p(1, 1, 0), p(1, 1, 1), p(1, 0, 1));  // +x
}

// Two rooms 5 m x 5 m x 3 m, A (x 0..5) and B (x 6..11), joined through a 1 m thick wall by a door
// 2 m wide (y 1.5..3.5) and 2.5 m high; floor z = 0 everywhere, a ceiling at 3 m, outer walls. In room
// A a pedestal 1 m high (x 0.5..1.5, y 3.5..4.5) and, with `step`, a platform 0.3 m high over
// x 2..3, y 0..5 (a step up and down on the way to the door).
inline Mesh two_room_level(bool step = false) {
  Mesh m;
  level_add_quad(m, {-1, -1, 0}, {12, -1, 0}, {12, 6, 0}, {-1, 6, 0});  // floor
  level_add_quad(m, {-1, -1, 3}, {-1, 6, 3}, {12, 6, 3}, {12, -1, 3});  // ceiling
  level_add_box(m, {-1, -1, 0}, {0, 6, 3});     // west wall
  level_add_box(m, {11, -1, 0}, {12, 6, 3});    // east wall
  level_add_box(m, {0, -1, 0}, {11, 0, 3});     // south wall
  level_add_box(m, {0, 5, 0}, {11, 6, 3});      // north wall
  level_add_box(m, {5, 0, 0}, {6, 1.5, 3});     // dividing wall, south of the door
  level_add_box(m, {5, 3.5, 0}, {6, 5, 3});     // north of the door
  level_add_box(m, {5, 1.5, 2.5}, {6, 3.5, 3}); // lintel
  level_add_box(m, {0.5, 3.5, 0}, {1.5, 4.5, 1});  // pedestal
  if (step) level_add_box(m, {2, 0, 0}, {3, 5, 0.3});
  return m;
}

// Waypoints of the two-room level, at spawn height (0.6 m above the floor): two per room, placed
// so that straight legs reach the door; then one on the pedestal (unreachable: a 1 m step) and one
// outside the level (no floor).
inline std::vector<glm::dvec3> two_room_waypoints() {
  return {{1, 1, 0.6}, {4, 2.5, 0.6}, {7, 2.5, 0.6}, {10, 4, 0.6}, {1, 4, 1.6}, {30, 30, 0.6}};
}

}  // namespace vtsim::test
