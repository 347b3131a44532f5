// docs/config.md carries the table `vtsim config --markdown` prints: keep them in sync.
#include <doctest/doctest.h>

#include <fstream>
#include <sstream>

#include "sim/replay_config.h"

TEST_CASE("docs/config.md lists every config key with its current default and why") {
  std::ifstream in(std::string(VTSIM_SOURCE_DIR) + "/docs/config.md");
  REQUIRE(in.good());
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string doc = ss.str();
  const std::string table = vtsim::replay_config_table().markdown(vtsim::ReplayConfig{});
  CHECK_MESSAGE(doc.find(table) != std::string::npos,
                "docs/config.md is out of date: regenerate its table with `build/vtsim config --markdown`");
}
