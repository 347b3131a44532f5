#pragma once
// Tile codecs: one per file in impl/codec_*.cpp, registered by one line each in codec_registry.cpp.
//
// A codec turns a tile's w x h x channels 8-bit texels (row-major, channels interleaved, no row
// padding) into bytes and back. decode() writes into a caller-provided buffer of exactly
// w * h * channels bytes and checks strictly: a payload that does not decode to exactly that many
// texels throws CodecError (the caller adds which tile; see TileStore::verify_and_decode).
//
// Thread-safety: a codec object is immutable after construction; encode() and decode() may be
// called from many threads at once. raw, zstd and lz4 decode without allocating (zstd keeps one
// decompression context per thread, made on the thread's first call); png and jpeg go through
// OpenImageIO, which allocates its reader per call.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "core/registry.h"
#include "stream/store/store_format.h"

namespace vtsim {

// A payload that is corrupt or does not match the expected texels; carries no location.
class CodecError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class ICodec {
 public:
  virtual ~ICodec() = default;
  virtual store::CodecId id() const = 0;
  virtual std::string_view name() const = 0;
  virtual bool lossless() const = 0;
  // Channel counts this codec stores (1..4 for most; JPEG only 1 and 3).
  virtual bool supports_channels(int channels) const = 0;
  // pixels: w*h*channels bytes. Returns the payload. Throws CodecError if the codec fails.
  virtual std::vector<std::uint8_t> encode(const std::uint8_t* pixels, int w, int h,
                                           int channels) const = 0;
  // Decodes `size` payload bytes into out[0, w*h*channels). Throws CodecError unless the payload
  // is well-formed and decodes to exactly that many bytes.
  virtual void decode(const std::uint8_t* bytes, std::size_t size, int w, int h, int channels,
                      std::uint8_t* out) const = 0;
};

// A codec's entry in the table (codec_registry.cpp).
struct CodecInfo {
  store::CodecId id;        // part of the file format: never renumbered
  std::string_view name;
  std::string_view spec;    // how --codec writes it with its parameter's range: "zstd[:1-22]"
  std::string_view why;
  int default_param;        // docs/store-format.md §3
  std::unique_ptr<ICodec> (*make)(int param);  // throws InputError for an out-of-range parameter
};
const Registry<CodecInfo>& codecs();

// A codec with its parameter (zstd level, lz4hc level or 0 for fast lz4, JPEG quality, PNG zlib
// level; ignored by raw). Throws InputError naming `where` for an out-of-range parameter.
std::unique_ptr<ICodec> make_codec(store::CodecId id, int param, const std::string& where = "codec");
// The default parameter of a codec (zstd 19... see codec_registry.cpp).
int default_codec_param(store::CodecId id);
// "zstd" -> CodecId::zstd; false for an unknown name.
bool codec_from_name(std::string_view name, store::CodecId& out);
std::string_view codec_name(store::CodecId id);
// A stateless decoder for any id (param-independent): the same object for every call.
const ICodec& decoder_for(store::CodecId id);

// "zstd:5" -> {zstd, 5}; "png" -> {png, default}. Throws InputError naming `where`.
struct CodecSpec {
  store::CodecId id = store::CodecId::raw;
  int param = 0;  // codec-specific (see make_codec)
};
CodecSpec parse_codec_spec(std::string_view text, const std::string& where);

}  // namespace vtsim
