// raw: the texels as they are. Decode is a bounds-checked memcpy (the reference for what the
// other codecs cost on top of IO).
#include <cstring>

#include "stream/store/i_codec.h"

namespace vtsim {
namespace {

class RawCodec final : public ICodec {
 public:
  store::CodecId id() const override { return store::CodecId::raw; }
  std::string_view name() const override { return "raw"; }
  bool lossless() const override { return true; }
  bool supports_channels(int c) const override { return c >= 1 && c <= 4; }
  std::vector<std::uint8_t> encode(const std::uint8_t* pixels, int w, int h, int c) const override {
    return std::vector<std::uint8_t>(pixels, pixels + static_cast<std::size_t>(w) * h * c);
  }
  void decode(const std::uint8_t* bytes, std::size_t size, int w, int h, int c,
              std::uint8_t* out) const override {
    const std::size_t want = static_cast<std::size_t>(w) * h * c;
    if (size != want)
      throw CodecError("raw payload is " + std::to_string(size) + " bytes, expected " + std::to_string(want));
    std::memcpy(out, bytes, want);
  }
};

}  // namespace

std::unique_ptr<ICodec> make_raw_codec(int /*param*/) { return std::make_unique<RawCodec>(); }

}  // namespace vtsim
