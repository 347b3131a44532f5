// zstd: lossless, level 1..22 (higher: smaller and slower to encode; decode speed barely depends
// on the level). Decode reuses one ZSTD_DCtx per thread and writes straight into the caller's
// buffer: no allocation after a thread's first tile.
#include <zstd.h>

#include <memory>

#include "core/error.h"
#include "stream/store/i_codec.h"

namespace vtsim {
namespace {

struct DctxDeleter {
  void operator()(ZSTD_DCtx* d) const { ZSTD_freeDCtx(d); }
};

class ZstdCodec final : public ICodec {
 public:
  explicit ZstdCodec(int level) : level_(level) {}
  store::CodecId id() const override { return store::CodecId::zstd; }
  std::string_view name() const override { return "zstd"; }
  bool lossless() const override { return true; }
  bool supports_channels(int c) const override { return c >= 1 && c <= 4; }

  std::vector<std::uint8_t> encode(const std::uint8_t* pixels, int w, int h, int c) const override {
    const std::size_t n = static_cast<std::size_t>(w) * h * c;
    std::vector<std::uint8_t> out(ZSTD_compressBound(n));
    const std::size_t r = ZSTD_compress(out.data(), out.size(), pixels, n, level_);
    if (ZSTD_isError(r)) throw CodecError(std::string("zstd compress: ") + ZSTD_getErrorName(r));
    out.resize(r);
    return out;
  }

  void decode(const std::uint8_t* bytes, std::size_t size, int w, int h, int c,
              std::uint8_t* out) const override {
    const std::size_t want = static_cast<std::size_t>(w) * h * c;
    const unsigned long long declared = ZSTD_getFrameContentSize(bytes, size);
    if (declared == ZSTD_CONTENTSIZE_ERROR) throw CodecError("zstd payload is not a zstd frame");
    if (declared != ZSTD_CONTENTSIZE_UNKNOWN && declared != want)
      throw CodecError("zstd frame holds " + std::to_string(declared) + " bytes, expected " + std::to_string(want));
    thread_local std::unique_ptr<ZSTD_DCtx, DctxDeleter> dctx(ZSTD_createDCtx());
    if (!dctx) throw CodecError("zstd: cannot create a decompression context");
    const std::size_t r = ZSTD_decompressDCtx(dctx.get(), out, want, bytes, size);
    if (ZSTD_isError(r)) throw CodecError(std::string("zstd decompress: ") + ZSTD_getErrorName(r));
    if (r != want)
      throw CodecError("zstd payload decoded to " + std::to_string(r) + " bytes, expected " + std::to_string(want));
  }

 private:
  int level_;
};

}  // namespace

std::unique_ptr<ICodec> make_zstd_codec(int level) {
  if (level < 1 || level > ZSTD_maxCLevel())
    throw InputError("zstd level", "must be 1.." + std::to_string(ZSTD_maxCLevel()) + ", got " + std::to_string(level));
  return std::make_unique<ZstdCodec>(level);
}

}  // namespace vtsim
