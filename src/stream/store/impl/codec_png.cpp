// png: lossless, 1-4 channels (gray, gray+alpha, RGB, RGBA), through OpenImageIO in memory.
// Parameter: zlib level 0..9 (default 6). Slower to decode than zstd/lz4; included because
// engines and artists already use it, and as a real-work decode for the decode pool.
#include "core/error.h"
#include "stream/store/i_codec.h"
#include "stream/store/impl/memory_image.h"

namespace vtsim {
namespace {

class PngCodec final : public ICodec {
 public:
  explicit PngCodec(int level) : level_(level) {}
  store::CodecId id() const override { return store::CodecId::png; }
  std::string_view name() const override { return "png"; }
  bool lossless() const override { return true; }
  bool supports_channels(int c) const override { return c >= 1 && c <= 4; }
  std::vector<std::uint8_t> encode(const std::uint8_t* pixels, int w, int h, int c) const override {
    return memory_image::encode("png", pixels, w, h, c, {{"png:compressionLevel", level_}});
  }
  void decode(const std::uint8_t* bytes, std::size_t size, int w, int h, int c,
              std::uint8_t* out) const override {
    memory_image::decode("png", bytes, size, w, h, c, out);
  }

 private:
  int level_;
};

}  // namespace

std::unique_ptr<ICodec> make_png_codec(int level) {
  if (level < 0 || level > 9) throw InputError("png level", "must be 0..9, got " + std::to_string(level));
  return std::make_unique<PngCodec>(level);
}

}  // namespace vtsim
