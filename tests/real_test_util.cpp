// The small store of the real-engine tests (real_test_util.h): generated once per build tree.
#include "real_test_util.h"

#include "stream/store/store_generator.h"

namespace vtsim::test {

namespace {

// Kept next to the test binary and reused by every test process (ctest runs each case in its own
// process): generated only when missing or unreadable, atomically (generate_store writes a
// temporary and renames it), so concurrent test processes are safe. The tests compare against
// the file's own contents, never against fixed bytes.
std::string store_beside_tests(const char* name, std::uint32_t border) {
  const std::string p = (std::filesystem::read_symlink("/proc/self/exe").parent_path() / name).string();
  try {
    const TileStore s = TileStore::open(p);
    if (s.geometry().width == 1024 && s.geometry().tile == 64 && s.layer_count() == 2 && s.geometry().border == border) return p;
  } catch (const std::exception&) {
  }
  GenOptions g;
  g.width = g.height = 1024;
  g.tile = 64;
  g.border = border;
  g.seed = 7;
  g.feature_texels = 256;
  g.layers = parse_gen_layers("albedo:zstd,normal:lz4", "layers");
  generate_store(g, p);
  return p;
}

}  // namespace

const std::string& small_store() {
  static const std::string path = store_beside_tests("real-test-small-v1.vts", 0);
  return path;
}

const std::string& small_vt_store() {
  static const std::string path = store_beside_tests("real-test-small-vt-v1.vts", 4);
  return path;
}

}  // namespace vtsim::test
