// The small store of the real-engine tests (real_test_util.h): generated once per process.
#include "real_test_util.h"

#include "stream/store_generator.h"

namespace vtsim::test {

const std::string& small_store() {
  static RealScratch dir;
  static const std::string path = [] {
    const std::string p = dir.file("small.vts");
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
