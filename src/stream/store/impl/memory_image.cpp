#include "stream/store/impl/memory_image.h"

#include "core/image_io.h"
#include "stream/store/i_codec.h"

namespace vtsim::memory_image {

std::vector<std::uint8_t> encode(const char* ext, const std::uint8_t* pixels, int w, int h, int c,
                                 const std::vector<std::pair<std::string, int>>& int_attrs) {
  std::vector<std::uint8_t> out;
  std::string e;
  if (!image_io::encode_memory(ext, pixels, w, h, c, int_attrs, out, e))
    throw CodecError(std::string(ext) + " encode: " + e);
  return out;
}

void decode(const char* ext, const std::uint8_t* bytes, std::size_t size, int w, int h, int c, std::uint8_t* out) {
  auto in = image_io::ImageReader::open_memory(ext, bytes, size);
  if (!in) {
    const std::string& e = in.error();
    throw CodecError(std::string(ext) + " payload does not open" + (e.empty() ? "" : ": " + e));
  }
  const image_io::ImageSpec& s = in.spec();
  if (s.width != w || s.height != h || s.channels != c || s.depth != 1)
    throw CodecError(std::string(ext) + " payload is " + std::to_string(s.width) + "x" + std::to_string(s.height) +
                     "x" + std::to_string(s.channels) + ", expected " + std::to_string(w) + "x" +
                     std::to_string(h) + "x" + std::to_string(c));
  // One reader thread: the decode pool owns the parallelism.
  switch (in.read(c, image_io::PixelType::u8, out, /*threads=*/1)) {
    case image_io::ReadStatus::ok: return;
    case image_io::ReadStatus::failed: {
      const std::string& e = in.error();
      throw CodecError(std::string(ext) + " payload does not decode" + (e.empty() ? "" : ": " + e));
    }
    case image_io::ReadStatus::ok_with_error:
      // libjpeg/libpng report some damage only as warnings; OIIO surfaces them as pending errors.
      throw CodecError(std::string(ext) + " payload is damaged: " + in.error());
  }
}

}  // namespace vtsim::memory_image
