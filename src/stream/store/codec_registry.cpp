// The codec table: adding a codec is one impl/codec_<name>.cpp plus one line in kCodecs.
// Ids are part of the file format (docs/store-format.md §3): never renumber one.
#include <charconv>
#include <string>

#include "core/error.h"
#include "stream/store/i_codec.h"

namespace vtsim {

std::unique_ptr<ICodec> make_raw_codec(int param);
std::unique_ptr<ICodec> make_zstd_codec(int level);
std::unique_ptr<ICodec> make_lz4_codec(int level);
std::unique_ptr<ICodec> make_png_codec(int level);
std::unique_ptr<ICodec> make_jpeg_codec(int quality);

namespace {

struct CodecEntry {
  store::CodecId id;
  std::string_view name;
  int default_param;  // why each default: see docs/store-format.md §3
  std::unique_ptr<ICodec> (*make)(int);
};

constexpr CodecEntry kCodecs[] = {
    {store::CodecId::raw, "raw", 0, make_raw_codec},
    {store::CodecId::zstd, "zstd", 9, make_zstd_codec},
    {store::CodecId::lz4, "lz4", 0, make_lz4_codec},
    {store::CodecId::png, "png", 6, make_png_codec},
    {store::CodecId::jpeg, "jpeg", 90, make_jpeg_codec},
};

const CodecEntry* entry(store::CodecId id) {
  for (const auto& e : kCodecs)
    if (e.id == id) return &e;
  return nullptr;
}

}  // namespace

std::unique_ptr<ICodec> make_codec(store::CodecId id, int param, const std::string& where) {
  const CodecEntry* e = entry(id);
  if (!e) throw InputError(where, "unknown codec id " + std::to_string(static_cast<std::uint32_t>(id)));
  try {
    return e->make(param);
  } catch (const InputError& err) {
    throw InputError(where, err.what());
  }
}

int default_codec_param(store::CodecId id) {
  const CodecEntry* e = entry(id);
  return e ? e->default_param : 0;
}

bool codec_from_name(std::string_view name, store::CodecId& out) {
  if (name == "jpg") name = "jpeg";
  for (const auto& e : kCodecs)
    if (e.name == name) {
      out = e.id;
      return true;
    }
  return false;
}

std::string_view codec_name(store::CodecId id) {
  const CodecEntry* e = entry(id);
  return e ? e->name : std::string_view("unknown");
}

const ICodec& decoder_for(store::CodecId id) {
  // Decoding does not depend on the parameter; one shared immutable object per id.
  static const std::unique_ptr<ICodec> decoders[] = {
      make_raw_codec(0), make_zstd_codec(1), make_lz4_codec(0), make_png_codec(6), make_jpeg_codec(90)};
  const auto i = static_cast<std::uint32_t>(id);
  if (i >= std::size(decoders)) throw CodecError("unknown codec id " + std::to_string(i));
  return *decoders[i];
}

CodecSpec parse_codec_spec(std::string_view text, const std::string& where) {
  CodecSpec spec;
  const auto colon = text.find(':');
  const std::string_view name = text.substr(0, colon);
  if (!codec_from_name(name, spec.id)) {
    std::string known;
    for (const auto& e : kCodecs) known += (known.empty() ? "" : ", ") + std::string(e.name);
    throw InputError(where, "unknown codec '" + std::string(name) + "' (known: " + known + ")");
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
