// Decode throughput of each tile codec on generated terrain tiles, single thread, against memcpy
// of the same decoded bytes measured side by side in the same run (the raw codec's cost; ratio =
// codec MB/s / memcpy MB/s), plus the XXH64 checksum pass every record pays. Compression ratio and
// encode speed (one pass) are in each case's params. bench/harness.h: medians of --reps
// repetitions (7 by default, 3 quick); --quick decodes 16 tiles per layer instead of 64.
//   build/bench/bench_store_codecs [--quick] [--reps N] [--json FILE] [--filter zstd]
#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <string>
#include <vector>

#include "harness.h"
#include "stream/store/i_codec.h"
#include "stream/store/store_generator.h"

using namespace vtsim;
using store::CodecId;

int main(int argc, char** argv) {
  bench::Harness h("store_codecs", argc, argv, 7, 3);
  const int tiles = h.pick(64, 16);
  GenOptions o;
  o.width = o.height = 8192;
  o.tile = 128;
  o.border = 4;
  o.seed = 1;
  o.layers = parse_gen_layers("albedo,normal", "layers");
  const int side = 136;
  struct Layer {
    const char* name;
    int channels;
    std::vector<std::vector<std::uint8_t>> texels;
  };
  std::vector<Layer> layers = {{"albedo", 3, {}}, {"normal", 3, {}}};
  for (int i = 0; i < tiles; ++i)
    for (std::uint32_t L = 0; L < 2; ++L)
      layers[L].texels.push_back(generate_tile(o, L, 0, std::uint64_t(i % 64), std::uint64_t(i / 64)));
  const double tile_bytes = double(side * side * 3);
  const double bytes = tile_bytes * double(tiles);
  h.param("tile", fmt::format("{}x{}x3 (128 + 2x4 border)", side, side));
  h.param("tiles_per_layer", tiles);

  volatile std::uint64_t sink = 0;
  for (const Layer& L : layers) {
    std::vector<std::uint8_t> out(static_cast<std::size_t>(tile_bytes));
    const bench::Side copy{"memcpy", {}, [&] {
                             for (const auto& t : L.texels) std::memcpy(out.data(), t.data(), t.size());
                             bench::do_not_optimize(out.data());
                           }};
    h.compare({.name = std::string(L.name) + "_xxh64", .metric = bench::Metric::kMBPerS, .work = bytes,
               .params = {{"layer", L.name}}, .target_ratio = 0},
              {"xxh64", {}, [&] {
                 for (const auto& t : L.texels) sink = sink + store::checksum64(t.data(), t.size());
               }},
              copy);
    for (const char* spec : {"zstd:3", "zstd:9", "zstd:19", "lz4", "lz4:9", "png", "jpeg:90"}) {
      const CodecSpec cs = parse_codec_spec(spec, "codec");
      const auto codec = make_codec(cs.id, cs.param);
      std::vector<std::vector<std::uint8_t>> enc;
      const auto e0 = std::chrono::steady_clock::now();
      for (const auto& t : L.texels) enc.push_back(codec->encode(t.data(), side, side, L.channels));
      const double enc_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - e0).count();
      double stored = 0;
      for (const auto& e : enc) stored += double(e.size());
      h.compare({.name = std::string(L.name) + "_" + spec, .metric = bench::Metric::kMBPerS, .work = bytes,
                 .params = {{"layer", L.name}, {"codec", spec}, {"compression_ratio", bytes / stored},
                            {"encode_MBps", bytes / enc_s / 1e6}},
                 .target_ratio = 0},
                {spec, {}, [&] {
                   for (const auto& e : enc) codec->decode(e.data(), e.size(), side, side, L.channels, out.data());
                   bench::do_not_optimize(out.data());
                 }},
                copy);
    }
  }
  return h.finish();
}
