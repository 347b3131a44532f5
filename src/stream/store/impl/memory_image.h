#pragma once
// Encoding and decoding whole PNG / JPEG images in memory (no temporary files) through the image
// module (core/image_io.h: OpenImageIO, loaded on first use). Shared by codec_png.cpp and
// codec_jpeg.cpp.
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace vtsim::memory_image {

// `ext` picks the format ("png", "jpg"); the integer attributes are set on the output spec.
// Throws CodecError if the encoder fails.
std::vector<std::uint8_t> encode(const char* ext, const std::uint8_t* pixels, int w, int h, int c,
                                 const std::vector<std::pair<std::string, int>>& int_attrs);
// Decodes into out[0, w*h*c); throws CodecError unless the payload is a w x h x c image.
void decode(const char* ext, const std::uint8_t* bytes, std::size_t size, int w, int h, int c,
            std::uint8_t* out);

}  // namespace vtsim::memory_image
