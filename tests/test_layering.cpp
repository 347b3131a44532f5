// The layer order of docs/architecture.md ("Rooms and floors") is the order the includes of src/
// follow: a file includes files of its own room and of rooms on lower floors only; rooms on one
// floor are independent. The table in the doc is what this test reads, so the doc and the rule
// cannot drift apart.
#include <doctest/doctest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <cctype>
#include <string>
#include <vector>

#include "test_util.h"

namespace {

struct Room {
  int floor = 0;
  std::string path;  // "src/stream/exec"
};

// Rows "| 3 | `src/stream/store` | ..." of the doc's table. (No std::regex: GCC 12 warns inside
// it at -O1 under the sanitizers.)
std::vector<Room> rooms_from_doc(const std::string& doc) {
  std::vector<Room> rooms;
  std::size_t b = 0;
  while (b < doc.size()) {
    const std::size_t e = std::min(doc.find('\n', b), doc.size());
    const std::string line = doc.substr(b, e - b);
    b = e + 1;
    // "| <digits> | `src/<path>` |"
    std::size_t i = 0;
    const auto skip_spaces = [&] {
      while (i < line.size() && line[i] == ' ') ++i;
    };
    if (line.empty() || line[0] != '|') continue;
    ++i;
    skip_spaces();
    const std::size_t d0 = i;
    while (i < line.size() && std::isdigit(static_cast<unsigned char>(line[i]))) ++i;
    if (i == d0) continue;
    const int floor = std::stoi(line.substr(d0, i - d0));
    skip_spaces();
    if (line.compare(i, 3, "| `") != 0) continue;
    i += 3;
    const std::size_t close = line.find('`', i);
    if (close == std::string::npos || line.compare(i, 4, "src/") != 0) continue;
    rooms.push_back({floor, line.substr(i, close - i)});
  }
  return rooms;
}

// The room a path lies in: the longest room path that is a prefix at a folder boundary.
const Room* room_of(const std::vector<Room>& rooms, const std::string& path) {
  const Room* best = nullptr;
  for (const Room& r : rooms)
    if (path.compare(0, r.path.size() + 1, r.path + "/") == 0 && (!best || r.path.size() > best->path.size()))
      best = &r;
  return best;
}

struct Include {
  std::string file;    // "src/cache/clipmap.h"
  int line = 0;
  std::string target;  // "src/core/view.h"
};

std::vector<Include> includes_of(const std::filesystem::path& root) {
  std::vector<Include> out;
  for (const auto& e : std::filesystem::recursive_directory_iterator(root / "src")) {
    const std::string ext = e.path().extension().string();
    if (!e.is_regular_file() || (ext != ".h" && ext != ".cpp")) continue;
    std::ifstream in(e.path());
    std::string text;
    int n = 0;
    const std::string rel = std::filesystem::relative(e.path(), root).generic_string();
    while (std::getline(in, text)) {
      ++n;
      // #include "path" (quoted: the project's own headers)
      std::size_t i = text.find_first_not_of(" \t");
      if (i == std::string::npos || text[i] != '#') continue;
      i = text.find_first_not_of(" \t", i + 1);
      if (i == std::string::npos || text.compare(i, 7, "include") != 0) continue;
      i = text.find_first_not_of(" \t", i + 7);
      if (i == std::string::npos || text[i] != '"') continue;
      const std::size_t close = text.find('"', i + 1);
      if (close != std::string::npos) out.push_back({rel, n, "src/" + text.substr(i + 1, close - i - 1)});
    }
  }
  std::sort(out.begin(), out.end(), [](const Include& a, const Include& b) { return a.file != b.file ? a.file < b.file : a.line < b.line; });
  return out;
}

std::vector<std::string> violations(const std::vector<Room>& rooms, const std::vector<Include>& includes,
                                    const std::filesystem::path& root) {
  std::vector<std::string> bad;
  for (const Include& i : includes) {
    const std::string at = i.file + ":" + std::to_string(i.line) + " includes \"" + i.target.substr(4) + "\"";
    const Room* from = room_of(rooms, i.file);
    const Room* to = room_of(rooms, i.target);
    if (!from) bad.push_back(at + ": " + i.file + " lies in no room of docs/architecture.md");
    else if (!std::filesystem::exists(root / i.target)) bad.push_back(at + ": no such file under src/");
    else if (!to) bad.push_back(at + ": " + i.target + " lies in no room of docs/architecture.md");
    else if (from != to && to->floor >= from->floor)
      bad.push_back(at + ": " + from->path + " (floor " + std::to_string(from->floor) + ") reaches " +
                    (to->floor == from->floor ? "across to " : "up to ") + to->path + " (floor " +
                    std::to_string(to->floor) + ")");
  }
  return bad;
}

}  // namespace

TEST_CASE("includes in src/ run down the floors of docs/architecture.md") {
  const std::filesystem::path root(VTSIM_SOURCE_DIR);
  const std::vector<Room> rooms = rooms_from_doc(vtsim::test::slurp((root / "docs/architecture.md").string()));
  REQUIRE_MESSAGE(rooms.size() >= 8, "docs/architecture.md has no table of rooms and floors");
  for (const Room& r : rooms) CHECK_MESSAGE(std::filesystem::is_directory(root / r.path), r.path << " is not a folder");
  const std::vector<Include> includes = includes_of(root);
  REQUIRE(includes.size() > 100);
  for (const std::string& v : violations(rooms, includes, root)) FAIL_CHECK(v);
}

TEST_CASE("the layering check catches an include that runs upward, across, or out of the rooms") {
  const std::vector<Room> rooms = {{1, "src/core"}, {2, "src/cache"}, {2, "src/image_module"}, {3, "src/stream/exec"}};
  const std::filesystem::path root(VTSIM_SOURCE_DIR);
  const auto check = [&](const std::string& file, const std::string& target) {
    return violations(rooms, {{file, 7, target}}, root);
  };
  CHECK(check("src/stream/exec/pipeline.h", "src/cache/need.h").empty());
  CHECK(check("src/cache/clipmap.h", "src/core/view.h").empty());
  CHECK(check("src/cache/clipmap.h", "src/cache/need.h").empty());
  const auto up = check("src/cache/clipmap.h", "src/stream/exec/pipeline.h");
  REQUIRE(up.size() == 1);
  CHECK(vtsim::test::contains(up[0], "src/cache/clipmap.h:7 includes \"stream/exec/pipeline.h\""));
  CHECK(vtsim::test::contains(up[0], "up to src/stream/exec (floor 3)"));
  const auto across = check("src/cache/clipmap.h", "src/image_module/oiio_module.cpp");
  REQUIRE(across.size() == 1);
  CHECK(vtsim::test::contains(across[0], "across to src/image_module"));
  CHECK(vtsim::test::contains(check("src/cli/main.cpp", "src/core/error.h").at(0), "lies in no room"));
  CHECK(vtsim::test::contains(check("src/core/view.h", "src/core/no_such.h").at(0), "no such file"));
}
