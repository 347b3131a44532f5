#pragma once
// Encoding and decoding whole images in memory through OpenImageIO's IOProxy (no temporary
// files): IOVecOutput to write, IOMemReader to read. Shared by codec_png.cpp and codec_jpeg.cpp.
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace vtsim::oiio_mem {

// `ext` picks the OIIO format ("png", "jpg"); attributes are set on the output spec.
std::vector<std::uint8_t> encode(const char* ext, const std::uint8_t* pixels, int w, int h, int c,
                                 const std::vector<std::pair<std::string, std::string>>& str_attrs,
                                 const std::vector<std::pair<std::string, int>>& int_attrs);
// Decodes into out[0, w*h*c); throws CodecError unless the payload is a w x h x c image.
void decode(const char* ext, const std::uint8_t* bytes, std::size_t size, int w, int h, int c,
            std::uint8_t* out);

}  // namespace vtsim::oiio_mem
