// The small store of the real-engine tests (real_test_util.h): generated once per build tree.
#include "real_test_util.h"

#include "stream/store_generator.h"

namespace vtsim::test {

const std::string& small_store() {
  // Kept next to the test binary and reused by every test process (ctest runs each case in its
  // own process): generated only when missing or unreadable, atomically (generate_store writes a
  // temporary and renames it), so concurrent test processes are safe. The tests compare against
  // the file's own contents, never against fixed bytes.
  static const std::string path = [] {
    const std::string p = (std::filesystem::read_symlink("/proc/self/exe").parent_path() / "real-test-small-v1.vts").string();
    try {
      const TileStore s = TileStore::open(p);
      if (s.geometry().width == 1024 && s.geometry().tile == 64 && s.layer_count() == 2 && s.geometry().border == 0) return p;
    } catch (const std::exception&) {
    }
    GenOptions g;
    g.width = g.height = 1024;
    g.tile = 64;
    g.border = 0;
    g.seed = 7;
    g.feature_texels = 256;
    g.layers = parse_gen_layers("albedo:zstd,normal:lz4", "layers");
    generate_store(g, p);
    return p;
  }();
  return path;
}

}  // namespace vtsim::test
