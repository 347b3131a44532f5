#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/error.h"
#include "level_test_util.h"
#include "sim/view/q3_entities.h"
#include "test_util.h"

using namespace vtsim;

namespace {

const char* kQ3Text =
    "{\n\"classname\" \"worldspawn\"\n\"message\" \"two rooms\"\n}\n"
    "{\n\"classname\" \"info_player_deathmatch\"\n\"angle\" \"180\"\n\"origin\" \"280 1416 -120\"\n}\n"
    "// a comment\n"
    "{ \"classname\" \"weapon_shotgun\" \"origin\" \"-8 16.5 24\" }\n"
    "{ \"classname\" \"team_CTF_redspawn\" \"origin\" \"1 2 3\" \"spawnflags\" \"1\" }\n";

// Expects parse_q3_bsp to throw an InputError naming the file and containing `what`.
void q3_expect_error(const std::string& bytes, const std::string& what, const Q3Limits& limits = {}) {
  try {
    parse_q3_bsp(bytes, "lvl.bsp", limits);
    FAIL("expected InputError");
  } catch (const InputError& e) {
    const std::string msg = e.what();
    CAPTURE(msg);
    CHECK(test::contains(msg, "lvl.bsp"));
    CHECK(test::contains(msg, what));
  }
}

std::string q3_temp(const std::string& name, const std::string& bytes) {
  const std::string path = (std::filesystem::temp_directory_path() / name).string();
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
  return path;
}

}  // namespace

TEST_CASE("q3 entities: the entity lump of a BSP is read whole, spawns and items recognised") {
  const auto es = parse_q3_bsp(test::make_q3_bsp(kQ3Text), "lvl.bsp");
  REQUIRE(es.size() == 4);
  CHECK(es[0].classname == "worldspawn");
  CHECK_FALSE(es[0].origin.has_value());
  CHECK(es[0].keys.size() == 2);
  CHECK(es[0].keys[1].second == "two rooms");
  CHECK(es[1].classname == "info_player_deathmatch");
  REQUIRE(es[1].origin.has_value());
  CHECK(*es[1].origin == glm::dvec3(280, 1416, -120));
  CHECK(es[1].angle_deg == 180.0);
  CHECK(is_q3_spawn(es[1]));
  CHECK_FALSE(is_q3_item(es[1]));
  CHECK(*es[2].origin == glm::dvec3(-8, 16.5, 24));
  CHECK(is_q3_item(es[2]));
  CHECK(is_q3_spawn(es[3]));
  CHECK(es[3].keys.size() == 3);
  // A trailing NUL (as the q3map compiler writes) ends the text; an empty lump has no entity.
  CHECK(parse_q3_bsp(test::make_q3_bsp(std::string(kQ3Text) + '\0' + "garbage"), "lvl.bsp").size() == 4);
  CHECK(parse_q3_bsp(test::make_q3_bsp(""), "lvl.bsp").empty());
}

TEST_CASE("q3 entities: malformed levels are refused with the file named") {
  q3_expect_error("IBSP", "shorter than a Quake 3 BSP header");
  q3_expect_error(test::make_q3_bsp(kQ3Text, 46, "RBSP"), "does not start with \"IBSP\"");
  q3_expect_error(test::make_q3_bsp(kQ3Text, 47), "BSP version 47, not 46");
  std::string cut = test::make_q3_bsp(kQ3Text);
  cut.resize(cut.size() - 10);
  q3_expect_error(cut, "outside the file");
  std::string negative = test::make_q3_bsp(kQ3Text);
  negative[11] = '\x80';  // offset becomes negative
  q3_expect_error(negative, "outside the file");
  Q3Limits small;
  small.max_entity_bytes = 16;
  q3_expect_error(test::make_q3_bsp(kQ3Text), "larger than the limit 16", small);
  Q3Limits few;
  few.max_entities = 2;
  q3_expect_error(test::make_q3_bsp(kQ3Text), "more than 2 entities", few);
  q3_expect_error(test::make_q3_bsp("{ \"classname\" \"x\n}"), "unterminated quoted string");
  q3_expect_error(test::make_q3_bsp("{ \"classname\" \"x\"\n"), "not closed");
  q3_expect_error(test::make_q3_bsp("{ \"classname\" }"), "has no value");
  q3_expect_error(test::make_q3_bsp("{ { }"), "'{' inside an entity");
  q3_expect_error(test::make_q3_bsp("\"classname\" \"x\""), "expected '{'");
  q3_expect_error(test::make_q3_bsp("{\n\"origin\" \"1 2\" }"), "entities line 2: \"origin\" \"1 2\": not three numbers");
  q3_expect_error(test::make_q3_bsp("{ \"origin\" \"1 2 3 4\" }"), "not three numbers");
  q3_expect_error(test::make_q3_bsp("{ \"origin\" \"1 nan 3\" }"), "not a finite number");
  q3_expect_error(test::make_q3_bsp("{ \"angle\" \"east\" }"), "\"angle\" \"east\": not a finite number");
}

TEST_CASE("q3 entities: read from a .bsp file and from a pk3 holding the map stored") {
  const std::string bsp = test::make_q3_bsp(kQ3Text);
  CHECK(read_q3_entities(q3_temp("vtsim_q3_test.bsp", bsp)).size() == 4);
  CHECK(read_q3_entities(q3_temp("vtsim_q3_test.pk3", test::make_zip("maps/lvl.bsp", bsp))).size() == 4);
  const auto refused = [](const std::string& path, const std::string& what) {
    try {
      read_q3_entities(path);
      FAIL("expected InputError");
    } catch (const InputError& e) {
      CAPTURE(e.what());
      CHECK(test::contains(e.what(), path));
      CHECK(test::contains(e.what(), what));
    }
  };
  refused(q3_temp("vtsim_q3_deflate.pk3", test::make_zip("maps/lvl.bsp", bsp, 8)), "fetch_levels.sh");
  refused(q3_temp("vtsim_q3_nomap.pk3", test::make_zip("textures/a.tga", bsp)), "holds 0 maps/*.bsp entries");
  std::string cut = test::make_zip("maps/lvl.bsp", bsp);
  refused(q3_temp("vtsim_q3_cut.pk3", cut.substr(0, cut.size() - 30)), "pk3 (zip)");
  refused((std::filesystem::temp_directory_path() / "vtsim_q3_missing.bsp").string(), "cannot open");
}
