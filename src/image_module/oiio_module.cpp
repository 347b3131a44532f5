// libvtsim_image.so: vtsim's image reading and writing through OpenImageIO, loaded with dlopen by
// core/image_io.cpp on the first image a process reads or writes. OpenImageIO pulls in ~250 shared
// libraries whose loading and static initialisers cost ~0.5 s of CPU per process; keeping it out of
// vtsim_lib means the CLI and every test process that touches no image never pays that.
//
// A thin wrapper: OpenImageIO calls and nothing else; the messages the library throws are composed
// on the caller's side. Nothing throws across the boundary (core/image_module_abi.h).
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "core/image_module_abi.h"

namespace OIIO = OIIO_NAMESPACE;
using namespace vtsim::image_abi;

struct vtsim::image_abi::Reader {
  std::unique_ptr<OIIO::Filesystem::IOMemReader> mem;  // outlives `in` (declared first)
  std::unique_ptr<OIIO::ImageInput> in;
};

namespace {

void set_error(char* err, std::size_t err_size, const std::string& msg) {
  if (err == nullptr || err_size == 0) return;
  const std::size_t n = std::min(msg.size(), err_size - 1);
  std::memcpy(err, msg.data(), n);
  err[n] = '\0';
}

// Runs f, turning an exception (bad_alloc, or one from OpenImageIO) into status `on_throw`.
template <class F>
Status guarded(char* err, std::size_t err_size, Status on_throw, F&& f) noexcept {
  try {
    set_error(err, err_size, "");
    return f();
  } catch (const std::exception& e) {
    set_error(err, err_size, std::string("exception in the image module: ") + e.what());
  } catch (...) {
    set_error(err, err_size, "unknown exception in the image module");
  }
  return on_throw;
}

OIIO::TypeDesc type_of(PixelType t) {
  switch (t) {
    case kU8: return OIIO::TypeDesc::UINT8;
    case kU16: return OIIO::TypeDesc::UINT16;
    case kF32: return OIIO::TypeDesc::FLOAT;
  }
  return OIIO::TypeDesc::UNKNOWN;
}

Spec spec_of(const OIIO::ImageInput& in) {
  const OIIO::ImageSpec& s = in.spec();
  Spec r{s.width,
         s.height,
         s.depth,
         s.nchannels,
         s.format == OIIO::TypeDesc::UINT8 ? 1 : 0,
         s.format.is_floating_point() ? 1 : 0,
         s.tile_width,
         s.tile_height,
         s.tile_width > 0 ? s.tile_depth : 0,
         {}};
  std::snprintf(r.format, sizeof r.format, "%s", in.format_name());
  return r;
}

// --- in-memory PNG / JPEG (the png and jpeg tile codecs) ---------------------------------------

Status encode_impl(const char* ext, const std::uint8_t* pixels, int w, int h, int c, const IntAttribute* attrs,
                   std::size_t nattrs, std::vector<unsigned char>& buf, std::string& error) {
  OIIO::Filesystem::IOVecOutput vec(buf);
  const std::string name = std::string("tile.") + ext;
  auto out = OIIO::ImageOutput::create(name, &vec);
  if (!out) {
    error = OIIO::geterror();
    return kCannotCreate;
  }
  OIIO::ImageSpec spec(w, h, c, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:UnassociatedAlpha", 1);
  for (std::size_t i = 0; i < nattrs; ++i) spec.attribute(attrs[i].name, attrs[i].value);
  if (!out->open(name, spec) || !out->write_image(OIIO::TypeDesc::UINT8, pixels) || !out->close()) {
    error = out->geterror();
    return kFailed;
  }
  return kOk;
}

Status open_memory_impl(const char* ext, const std::uint8_t* bytes, std::size_t size, Reader& r, std::string& error) {
  r.mem = std::make_unique<OIIO::Filesystem::IOMemReader>(bytes, size);
  const std::string name = std::string("tile.") + ext;
  // OIIO 2.4's format plugins pick the proxy up from the config hint, not only from open()'s
  // argument; pass it both ways.
  OIIO::ImageSpec config;
  void* proxy = r.mem.get();
  config.attribute("oiio:ioproxy", OIIO::TypeDesc::PTR, &proxy);
  // Texels are data: keep alpha unassociated (PNG's own convention), no (un)premultiplying.
  config.attribute("oiio:UnassociatedAlpha", 1);
  r.in = OIIO::ImageInput::open(name, &config, r.mem.get());
  if (!r.in) {
    error = OIIO::geterror();
    return kCannotOpen;
  }
  return kOk;
}

// OIIO interns attribute and format names in a global ustring table on first use, guarded by its
// own spin lock. One PNG and JPEG round trip per channel count, once, before any concurrent use,
// interns every name these codecs touch, so worker threads only ever read the table (and
// ThreadSanitizer, which cannot see OIIO's uninstrumented lock, has no first-use writes to flag).
void prewarm() {
  static std::once_flag once;
  std::call_once(once, [] {
    const std::uint8_t px[4 * 4 * 4] = {};
    std::uint8_t out[4 * 4 * 4];
    std::string error;
    const auto round_trip = [&](const char* ext, int c, const IntAttribute& attr) {
      std::vector<unsigned char> buf;
      if (encode_impl(ext, px, 4, 4, c, &attr, 1, buf, error) != kOk) return;
      Reader r;
      if (open_memory_impl(ext, buf.data(), buf.size(), r, error) != kOk) return;
      r.in->threads(1);
      r.in->read_image(0, 0, 0, c, OIIO::TypeDesc::UINT8, out);
      r.in->has_error();
    };
    for (int c = 1; c <= 4; ++c) {
      round_trip("png", c, {"png:compressionLevel", 6});
      if (c == 1 || c == 3) round_trip("jpg", c, {"CompressionQuality", 90});
    }
    OIIO::geterror();
  });
}

// --- the table ----------------------------------------------------------------------------------

Status open_file(const char* path, std::int32_t unassociated_alpha, Reader** out, Spec* spec, char* err,
                 std::size_t err_size) {
  *out = nullptr;
  return guarded(err, err_size, kCannotOpen, [&] {
    auto r = std::make_unique<Reader>();
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);  // texels as stored, alpha not multiplied in
    r->in = OIIO::ImageInput::open(path, unassociated_alpha ? &config : nullptr);
    if (!r->in) {
      set_error(err, err_size, OIIO::geterror());
      return kCannotOpen;
    }
    *spec = spec_of(*r->in);
    *out = r.release();
    return kOk;
  });
}

Status open_memory(const char* ext, const std::uint8_t* bytes, std::size_t size, Reader** out, Spec* spec, char* err,
                   std::size_t err_size) {
  *out = nullptr;
  return guarded(err, err_size, kCannotOpen, [&] {
    prewarm();
    auto r = std::make_unique<Reader>();
    std::string error;
    const Status s = open_memory_impl(ext, bytes, size, *r, error);
    if (s != kOk) {
      set_error(err, err_size, error);
      return s;
    }
    *spec = spec_of(*r->in);
    *out = r.release();
    return kOk;
  });
}

// One read's outcome: ok, or the reader's error as failed / (pixels read) ok-with-error.
Status finish_read(Reader* r, bool ok, char* err, std::size_t err_size) {
  if (!ok) {
    set_error(err, err_size, r->in->geterror());
    return kFailed;
  }
  // libjpeg/libpng report some damage only as warnings; OIIO surfaces them as pending errors.
  if (r->in->has_error()) {
    set_error(err, err_size, r->in->geterror());
    return kOkWithError;
  }
  return kOk;
}

Status read(Reader* r, std::int32_t nchannels, PixelType type, void* out, std::int32_t threads, char* err,
            std::size_t err_size) {
  return guarded(err, err_size, kFailed, [&] {
    if (threads > 0) r->in->threads(threads);
    return finish_read(r, r->in->read_image(0, 0, 0, nchannels, type_of(type), out), err, err_size);
  });
}

Status read_rows(Reader* r, std::int32_t ybegin, std::int32_t yend, std::int32_t nchannels, PixelType type, void* out,
                 std::int32_t threads, char* err, std::size_t err_size) {
  return guarded(err, err_size, kFailed, [&] {
    if (threads > 0) r->in->threads(threads);
    const OIIO::ImageSpec& s = r->in->spec();
    const bool ok = s.tile_width > 0
                        ? r->in->read_tiles(0, 0, s.x, s.x + s.width, s.y + ybegin, s.y + yend, s.z, s.z + 1, 0,
                                            nchannels, type_of(type), out)
                        : r->in->read_scanlines(0, 0, s.y + ybegin, s.y + yend, s.z, 0, nchannels, type_of(type), out);
    return finish_read(r, ok, err, err_size);
  });
}

void close(Reader* r) {
  try {
    if (r != nullptr && r->in) r->in->close();
  } catch (...) {
  }
  delete r;
}

Status write_file(const char* path, std::int32_t w, std::int32_t h, std::int32_t c, PixelType type, const void* pixels,
                  std::int32_t unassociated_alpha, char* err, std::size_t err_size) {
  return guarded(err, err_size, kFailed, [&] {
    auto out = OIIO::ImageOutput::create(path);
    if (!out) {
      set_error(err, err_size, OIIO::geterror());
      return kCannotCreate;
    }
    OIIO::ImageSpec spec(w, h, c, type_of(type));
    if (unassociated_alpha) spec.attribute("oiio:UnassociatedAlpha", 1);
    if (!out->open(path, spec) || !out->write_image(type_of(type), pixels) || !out->close()) {
      set_error(err, err_size, out->geterror());
      return kFailed;
    }
    return kOk;
  });
}

Status encode_memory(const char* ext, const std::uint8_t* pixels, std::int32_t w, std::int32_t h, std::int32_t c,
                     const IntAttribute* attrs, std::size_t nattrs, std::uint8_t** out, std::size_t* out_size,
                     char* err, std::size_t err_size) {
  *out = nullptr;
  *out_size = 0;
  return guarded(err, err_size, kFailed, [&] {
    prewarm();
    std::vector<unsigned char> buf;
    std::string error;
    const Status s = encode_impl(ext, pixels, w, h, c, attrs, nattrs, buf, error);
    if (s != kOk) {
      set_error(err, err_size, error);
      return s;
    }
    auto* bytes = static_cast<std::uint8_t*>(std::malloc(std::max<std::size_t>(buf.size(), 1)));
    if (bytes == nullptr) throw std::bad_alloc();
    if (!buf.empty()) std::memcpy(bytes, buf.data(), buf.size());
    *out = bytes;
    *out_size = buf.size();
    return kOk;
  });
}

void free_bytes(std::uint8_t* bytes) { std::free(bytes); }

constexpr Api kApi = {kAbiVersion, sizeof(Api), open_file,     open_memory, read,
                      read_rows,   close,       write_file, encode_memory, free_bytes};

}  // namespace

static_assert(std::string_view(kEntrySymbol) == "vtsim_image_module_api");
extern "C" __attribute__((visibility("default"))) const Api* vtsim_image_module_api() { return &kApi; }
