// The codec table: adding a codec is one impl/codec_<name>.cpp plus one line in codecs() (and
// its make function declared above it).
// Ids are part of the file format (docs/store-format.md §3): never renumber one.
#include <charconv>
#include <string>
#include <vector>

#include "core/error.h"
#include "stream/store/i_codec.h"

namespace vtsim {

std::unique_ptr<ICodec> make_raw_codec(int param);
std::unique_ptr<ICodec> make_zstd_codec(int level);
std::unique_ptr<ICodec> make_lz4_codec(int level);
std::unique_ptr<ICodec> make_png_codec(int level);
std::unique_ptr<ICodec> make_jpeg_codec(int quality);

const Registry<CodecInfo>& codecs() {
  // Why each default parameter: docs/store-format.md §3.
  static const Registry<CodecInfo> table(
      "codec",
      {
          {store::CodecId::raw, "raw", "raw", "uncompressed texels: no decode cost, the most disk bytes", 0, make_raw_codec},
          {store::CodecId::zstd, "zstd", "zstd[:1-22]", "Zstandard, lossless (level 9 by default): small tiles, decode speed barely depends on the level",
           9, make_zstd_codec},
          {store::CodecId::lz4, "lz4", "lz4[:0|3-12]", "LZ4, lossless (0 = fast LZ4, 3-12 = LZ4HC level): the fastest decode, larger tiles", 0,
           make_lz4_codec},
          {store::CodecId::png, "png", "png[:0-9]", "PNG through OpenImageIO, lossless (zlib level 6 by default): slow decode, allocates per call",
           6, make_png_codec},
          {store::CodecId::jpeg, "jpeg", "jpeg[:1-100]", "JPEG through OpenImageIO, lossy (quality 90 by default; also jpg): 1 or 3 channels",
           90, make_jpeg_codec},
      });
  return table;
}

namespace {

const CodecInfo* entry(store::CodecId id) {
  for (const auto& e : codecs().entries())
    if (e.id == id) return &e;
  return nullptr;
}

}  // namespace

std::unique_ptr<ICodec> make_codec(store::CodecId id, int param, const std::string& where) {
  const CodecInfo* e = entry(id);
  if (!e) throw InputError(where, "unknown codec id " + std::to_string(static_cast<std::uint32_t>(id)));
  try {
    return e->make(param);
  } catch (const InputError& err) {
    throw InputError(where, err.what());
  }
}

int default_codec_param(store::CodecId id) {
  const CodecInfo* e = entry(id);
  return e ? e->default_param : 0;
}

bool codec_from_name(std::string_view name, store::CodecId& out) {
  if (name == "jpg") name = "jpeg";
  const CodecInfo* e = codecs().find(name);
  if (e) out = e->id;
  return e != nullptr;
}

std::string_view codec_name(store::CodecId id) {
  const CodecInfo* e = entry(id);
  return e ? e->name : std::string_view("unknown");
}

const ICodec& decoder_for(store::CodecId id) {
  // Decoding does not depend on the parameter: one shared immutable object per id, made with the
  // default parameter.
  static const std::vector<std::unique_ptr<ICodec>> decoders = [] {
    std::vector<std::unique_ptr<ICodec>> d;
    for (const CodecInfo& e : codecs().entries()) {
      const auto i = static_cast<std::size_t>(e.id);
      if (d.size() <= i) d.resize(i + 1);
      d[i] = e.make(e.default_param);
    }
    return d;
  }();
  const auto i = static_cast<std::uint32_t>(id);
  if (i >= decoders.size() || !decoders[i]) throw CodecError("unknown codec id " + std::to_string(i));
  return *decoders[i];
}

CodecSpec parse_codec_spec(std::string_view text, const std::string& where) {
  CodecSpec spec;
  const auto colon = text.find(':');
  const std::string_view name = text.substr(0, colon);
  if (!codec_from_name(name, spec.id)) {
    throw InputError(where, "unknown codec '" + std::string(name) + "' (known: " + codecs().names() + ")");
  }
  spec.param = default_codec_param(spec.id);
  if (colon != std::string_view::npos) {
    const std::string_view p = text.substr(colon + 1);
    auto [ptr, ec] = std::from_chars(p.data(), p.data() + p.size(), spec.param);
    if (ec != std::errc() || ptr != p.data() + p.size() || p.empty())
      throw InputError(where, "codec parameter '" + std::string(p) + "' is not an integer");
  }
  make_codec(spec.id, spec.param, where);  // range check now, not halfway through a build
  return spec;
}

}  // namespace vtsim
