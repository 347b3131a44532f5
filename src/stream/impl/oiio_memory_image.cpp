#include "stream/impl/oiio_memory_image.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <mutex>

#include "stream/i_codec.h"

namespace vtsim::oiio_mem {

namespace OIIO = OIIO_NAMESPACE;

namespace {

std::vector<std::uint8_t> encode_impl(const char* ext, const std::uint8_t* pixels, int w, int h, int c,
                                      const std::vector<std::pair<std::string, std::string>>& str_attrs,
                                      const std::vector<std::pair<std::string, int>>& int_attrs);
void decode_impl(const char* ext, const std::uint8_t* bytes, std::size_t size, int w, int h, int c, std::uint8_t* out);

// OIIO interns attribute and format names in a global ustring table on first use, guarded by its
// own spin lock. One PNG and JPEG round trip per channel count, once, before any concurrent use,
// interns every name these codecs touch, so worker threads only ever read the table (and
// ThreadSanitizer, which cannot see OIIO's uninstrumented lock, has no first-use writes to flag).
void prewarm() {
  static std::once_flag once;
  std::call_once(once, [] {
    const std::uint8_t px[4 * 4 * 4] = {};
    std::uint8_t out[4 * 4 * 4];
    for (int c = 1; c <= 4; ++c) {
      const auto png = encode_impl("png", px, 4, 4, c, {}, {{"png:compressionLevel", 6}});
      decode_impl("png", png.data(), png.size(), 4, 4, c, out);
      if (c == 1 || c == 3) {
        const auto jpg = encode_impl("jpg", px, 4, 4, c, {}, {{"CompressionQuality", 90}});
        decode_impl("jpg", jpg.data(), jpg.size(), 4, 4, c, out);
      }
    }
    OIIO::geterror();
  });
}

}  // namespace

std::vector<std::uint8_t> encode(const char* ext, const std::uint8_t* pixels, int w, int h, int c,
                                 const std::vector<std::pair<std::string, std::string>>& str_attrs,
                                 const std::vector<std::pair<std::string, int>>& int_attrs) {
  prewarm();
  return encode_impl(ext, pixels, w, h, c, str_attrs, int_attrs);
}

void decode(const char* ext, const std::uint8_t* bytes, std::size_t size, int w, int h, int c, std::uint8_t* out) {
  prewarm();
  decode_impl(ext, bytes, size, w, h, c, out);
}

namespace {

std::vector<std::uint8_t> encode_impl(const char* ext, const std::uint8_t* pixels, int w, int h, int c,
                                      const std::vector<std::pair<std::string, std::string>>& str_attrs,
                                      const std::vector<std::pair<std::string, int>>& int_attrs) {
  std::vector<unsigned char> buf;
  OIIO::Filesystem::IOVecOutput vec(buf);
  const std::string name = std::string("tile.") + ext;
  auto out = OIIO::ImageOutput::create(name, &vec);
  if (!out) throw CodecError(std::string(ext) + " encode: " + OIIO::geterror());
  OIIO::ImageSpec spec(w, h, c, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:UnassociatedAlpha", 1);
  for (const auto& [k, v] : str_attrs) spec.attribute(k, v);
  for (const auto& [k, v] : int_attrs) spec.attribute(k, v);
  if (!out->open(name, spec) || !out->write_image(OIIO::TypeDesc::UINT8, pixels) || !out->close())
    throw CodecError(std::string(ext) + " encode: " + out->geterror());
  return std::vector<std::uint8_t>(buf.begin(), buf.end());
}

void decode_impl(const char* ext, const std::uint8_t* bytes, std::size_t size, int w, int h, int c, std::uint8_t* out) {
  OIIO::Filesystem::IOMemReader mem(bytes, size);
  const std::string name = std::string("tile.") + ext;
  // OIIO 2.4's format plugins pick the proxy up from the config hint, not only from open()'s
  // argument; pass it both ways.
  OIIO::ImageSpec config;
  void* proxy = &mem;
  config.attribute("oiio:ioproxy", OIIO::TypeDesc::PTR, &proxy);
  // Texels are data: keep alpha unassociated (PNG's own convention), no (un)premultiplying.
  config.attribute("oiio:UnassociatedAlpha", 1);
  auto in = OIIO::ImageInput::open(name, &config, &mem);
  if (!in) {
    std::string e = OIIO::geterror();
    throw CodecError(std::string(ext) + " payload does not open" + (e.empty() ? "" : ": " + e));
  }
  const OIIO::ImageSpec& s = in->spec();
  if (s.width != w || s.height != h || s.nchannels != c || s.depth != 1)
    throw CodecError(std::string(ext) + " payload is " + std::to_string(s.width) + "x" + std::to_string(s.height) +
                     "x" + std::to_string(s.nchannels) + ", expected " + std::to_string(w) + "x" +
                     std::to_string(h) + "x" + std::to_string(c));
  in->threads(1);  // the decode pool owns the parallelism
  if (!in->read_image(0, 0, 0, c, OIIO::TypeDesc::UINT8, out)) {
    std::string e = in->geterror();
    throw CodecError(std::string(ext) + " payload does not decode" + (e.empty() ? "" : ": " + e));
  }
  // libjpeg/libpng report some damage only as warnings; OIIO surfaces them as pending errors.
  if (in->has_error()) throw CodecError(std::string(ext) + " payload is damaged: " + in->geterror());
}

}  // namespace
}  // namespace vtsim::oiio_mem
