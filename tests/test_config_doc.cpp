// docs/config.md carries the reference `vtsim config --markdown` prints (every key, then every
// registry's entries): keep them in sync.
#include <doctest/doctest.h>

#include "sim/run/replay_config.h"
#include "test_util.h"

TEST_CASE("docs/config.md lists every config key with its current default and why, and every registry entry") {
  const std::string doc = vtsim::test::slurp(std::string(VTSIM_SOURCE_DIR) + "/docs/config.md");
  REQUIRE_MESSAGE(!doc.empty(), "docs/config.md is missing or empty");
  const std::string table = vtsim::config_reference_markdown();
  CHECK_MESSAGE(doc.find(table) != std::string::npos,
                "docs/config.md is out of date: regenerate its table with `build/vtsim config --markdown`");
}
