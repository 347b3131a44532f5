// jpeg: lossy, 1 or 3 channels (JPEG has no alpha or two-channel form), through OpenImageIO in
// memory. Parameter: quality 1..100 (default 90). The real-work decode of Yao 2007 §4-3 ("JPEG
// read per block and decompressed in real time on multi-core systems").
#include "core/error.h"
#include "stream/store/i_codec.h"
#include "stream/store/impl/memory_image.h"

namespace vtsim {
namespace {

class JpegCodec final : public ICodec {
 public:
  explicit JpegCodec(int quality) : quality_(quality) {}
  store::CodecId id() const override { return store::CodecId::jpeg; }
  std::string_view name() const override { return "jpeg"; }
  bool lossless() const override { return false; }
  bool supports_channels(int c) const override { return c == 1 || c == 3; }
  std::vector<std::uint8_t> encode(const std::uint8_t* pixels, int w, int h, int c) const override {
    if (!supports_channels(c)) throw CodecError("jpeg stores 1 or 3 channels, not " + std::to_string(c));
    // An int attribute, not "Compression" = "jpeg:Q": OIIO interns string values globally.
    return memory_image::encode("jpg", pixels, w, h, c, {{"CompressionQuality", quality_}});
  }
  void decode(const std::uint8_t* bytes, std::size_t size, int w, int h, int c,
              std::uint8_t* out) const override {
    memory_image::decode("jpg", bytes, size, w, h, c, out);
  }

 private:
  int quality_;
};

}  // namespace

std::unique_ptr<ICodec> make_jpeg_codec(int quality) {
  if (quality < 1 || quality > 100)
    throw InputError("jpeg quality", "must be 1..100, got " + std::to_string(quality));
  return std::make_unique<JpegCodec>(quality);
}

}  // namespace vtsim
