// Decode throughput of each tile codec on generated terrain tiles, single thread, as a ratio to
// memcpy of the same decoded bytes measured in the same run (the raw codec's cost), plus the
// XXH64 checksum pass every record pays. Median of --reps repetitions.
//   build/bench/bench_store_codecs [tiles=64] [reps=7]
#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <string>
#include <vector>

#include "stream/i_codec.h"
#include "stream/store_generator.h"

using namespace vtsim;
using store::CodecId;

namespace {

template <class F>
double median_seconds(int reps, F&& f) {
  std::vector<double> t;
  for (int r = 0; r < reps; ++r) {
    const auto a = std::chrono::steady_clock::now();
    f();
    t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count());
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  const int tiles = argc > 1 ? std::stoi(argv[1]) : 64;
  const int reps = argc > 2 ? std::stoi(argv[2]) : 7;
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

  fmt::print("tile {}x{}x3, {} tiles per layer, median of {} reps, one thread\n", side, side, tiles, reps);
  fmt::print("{:<8} {:<10} {:>8} {:>12} {:>14} {:>10}\n", "layer", "codec", "ratio", "encode MB/s", "decode MB/s", "vs memcpy");
  for (const Layer& L : layers) {
    std::vector<std::uint8_t> out(static_cast<std::size_t>(tile_bytes));
    const double t_copy = median_seconds(reps, [&] {
      for (const auto& t : L.texels) std::memcpy(out.data(), t.data(), t.size());
    });
    const double t_sum = median_seconds(reps, [&] {
      volatile std::uint64_t s = 0;
      for (const auto& t : L.texels) s = s + store::checksum64(t.data(), t.size());
    });
    const double mb = tile_bytes * double(tiles) / 1e6;
    fmt::print("{:<8} {:<10} {:>8} {:>12} {:>14.0f} {:>10.3f}\n", L.name, "memcpy", "1.00", "-", mb / t_copy, 1.0);
    fmt::print("{:<8} {:<10} {:>8} {:>12} {:>14.0f} {:>10.3f}\n", L.name, "xxh64", "-", "-", mb / t_sum, t_copy / t_sum);
    for (const char* spec : {"zstd:3", "zstd:9", "zstd:19", "lz4", "lz4:9", "png", "jpeg:90"}) {
      const CodecSpec cs = parse_codec_spec(spec, "codec");
      const auto codec = make_codec(cs.id, cs.param);
      std::vector<std::vector<std::uint8_t>> enc;
      const double t_enc = median_seconds(1, [&] {
        for (const auto& t : L.texels) enc.push_back(codec->encode(t.data(), side, side, L.channels));
      });
      double stored = 0;
      for (const auto& e : enc) stored += double(e.size());
      const double t_dec = median_seconds(reps, [&] {
        for (const auto& e : enc) codec->decode(e.data(), e.size(), side, side, L.channels, out.data());
      });
      fmt::print("{:<8} {:<10} {:>8.2f} {:>12.0f} {:>14.0f} {:>10.3f}\n", L.name, spec, tile_bytes * double(tiles) / stored,
                 mb / t_enc, mb / t_dec, t_copy / t_dec);
    }
  }
  return 0;
}
