// lz4: lossless and the fastest to decode (several GB/s per core). Level 0 is LZ4's fast
// compressor; 3..12 select LZ4HC (smaller files, slower encode, same decode). The payload is a
// raw LZ4 block: its decoded size is the tile size, which the caller knows.
#include <lz4.h>
#include <lz4hc.h>

#include "core/error.h"
#include "stream/store/i_codec.h"

namespace vtsim {
namespace {

class Lz4Codec final : public ICodec {
 public:
  explicit Lz4Codec(int level) : level_(level) {}
  store::CodecId id() const override { return store::CodecId::lz4; }
  std::string_view name() const override { return "lz4"; }
  bool lossless() const override { return true; }
  bool supports_channels(int c) const override { return c >= 1 && c <= 4; }

  std::vector<std::uint8_t> encode(const std::uint8_t* pixels, int w, int h, int c) const override {
    const int n = w * h * c;
    std::vector<std::uint8_t> out(static_cast<std::size_t>(LZ4_compressBound(n)));
    const char* src = reinterpret_cast<const char*>(pixels);
    char* dst = reinterpret_cast<char*>(out.data());
    const int cap = static_cast<int>(out.size());
    const int r = level_ == 0 ? LZ4_compress_default(src, dst, n, cap)
                              : LZ4_compress_HC(src, dst, n, cap, level_);
    if (r <= 0) throw CodecError("lz4 compress failed");
    out.resize(static_cast<std::size_t>(r));
    return out;
  }

  void decode(const std::uint8_t* bytes, std::size_t size, int w, int h, int c,
              std::uint8_t* out) const override {
    const int want = w * h * c;
    if (size > static_cast<std::size_t>(LZ4_compressBound(want)))
      throw CodecError("lz4 payload of " + std::to_string(size) + " bytes is larger than any block of " +
                       std::to_string(want) + " bytes compresses to");
    const int r = LZ4_decompress_safe(reinterpret_cast<const char*>(bytes), reinterpret_cast<char*>(out),
                                      static_cast<int>(size), want);
    if (r < 0) throw CodecError("lz4 payload is corrupt");
    if (r != want)
      throw CodecError("lz4 payload decoded to " + std::to_string(r) + " bytes, expected " + std::to_string(want));
  }

 private:
  int level_;
};

}  // namespace

std::unique_ptr<ICodec> make_lz4_codec(int level) {
  if (level != 0 && (level < 3 || level > LZ4HC_CLEVEL_MAX))
    throw InputError("lz4 level", "must be 0 (fast) or 3.." + std::to_string(LZ4HC_CLEVEL_MAX) +
                                      " (HC), got " + std::to_string(level));
  return std::make_unique<Lz4Codec>(level);
}

}  // namespace vtsim
