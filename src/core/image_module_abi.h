#pragma once
// The binary interface between vtsim_lib's image loader (core/image_io.cpp) and the image module
// (src/image_module/oiio_module.cpp, built as libvtsim_image.so: the only code linked to
// OpenImageIO). The loader dlopens the module on the first image read or write and looks up one
// C symbol, kEntrySymbol, which returns a table of plain function pointers.
//
// Rules of the boundary: C types only (no std::string, no containers, no exceptions). Every
// function that can fail returns a Status and copies a message (truncated, NUL-terminated) into
// the caller's err[err_size]; the loader turns it into the same InputError / CodecError text the
// library threw when it called OpenImageIO directly. Bytes the module allocates (encode_memory)
// are freed by the module (free_bytes). Change any signature or field: bump kAbiVersion.
#include <cstddef>
#include <cstdint>

namespace vtsim::image_abi {

inline constexpr std::uint32_t kAbiVersion = 3;  // 2: Spec's tile size, read_rows; 3: Spec's format
inline constexpr const char* kEntrySymbol = "vtsim_image_module_api";
inline constexpr const char* kModuleFileName = "libvtsim_image.so";

// Pixel types the caller reads or writes (OpenImageIO converts from and to the file's own).
enum PixelType : std::int32_t { kU8 = 1, kU16 = 2, kF32 = 3 };

enum Status : std::int32_t {
  kOk = 0,
  kCannotOpen = 1,    // open_*: the file or payload does not open (err: OpenImageIO's global error)
  kCannotCreate = 1,  // write_file / encode_memory: no writer for this format (err: global error)
  kFailed = 2,        // read / write / encode failed (err: the reader's or writer's error)
  kOkWithError = 3,   // read: pixels read, but the reader reports a pending error (damage)
};

struct Spec {
  std::int32_t width, height, depth, nchannels;
  std::int32_t is_uint8;  // the file's pixels are 8-bit unsigned
  std::int32_t is_float;  // ... are floating point (half, float, double)
  std::int32_t tile_width, tile_height, tile_depth;  // the file's tile size; 0 x 0 x 0 for scanline files
  char format[32];  // OpenImageIO's reader name ("tiff", "jpeg2000", ...), NUL-terminated, cut to fit
};

struct IntAttribute {
  const char* name;
  std::int32_t value;
};

struct Reader;  // opaque: an OpenImageIO ImageInput (and its memory proxy)

struct Api {
  std::uint32_t abi_version;  // kAbiVersion of the module
  std::uint32_t struct_size;  // sizeof(Api) of the module

  // Opens `path`; unassociated_alpha != 0 keeps alpha as stored (no premultiplying).
  Status (*open_file)(const char* path, std::int32_t unassociated_alpha, Reader** out, Spec* spec, char* err,
                      std::size_t err_size);
  // Opens an in-memory file of format `ext` ("png", "jpg"), alpha unassociated. bytes[0, size)
  // must stay valid until close().
  Status (*open_memory)(const char* ext, const std::uint8_t* bytes, std::size_t size, Reader** out, Spec* spec,
                        char* err, std::size_t err_size);
  // Reads channels [0, nchannels) of the whole first subimage as `type` into out. threads: the
  // reader's worker threads (0: OpenImageIO's default).
  Status (*read)(Reader* reader, std::int32_t nchannels, PixelType type, void* out, std::int32_t threads, char* err,
                 std::size_t err_size);
  // Reads rows [ybegin, yend) of the first subimage the same way into out (width*(yend-ybegin)
  // pixels). Tiled files: ybegin a multiple of the tile height, and yend too unless it is the
  // image's height.
  Status (*read_rows)(Reader* reader, std::int32_t ybegin, std::int32_t yend, std::int32_t nchannels, PixelType type,
                      void* out, std::int32_t threads, char* err, std::size_t err_size);
  void (*close)(Reader* reader);  // null is fine

  // Writes a w x h x c image of `type` to `path` (format from the extension).
  Status (*write_file)(const char* path, std::int32_t w, std::int32_t h, std::int32_t c, PixelType type,
                       const void* pixels, std::int32_t unassociated_alpha, char* err, std::size_t err_size);
  // Encodes an 8-bit w x h x c image as a file of format `ext` in memory, with integer attributes
  // on the output spec; on kOk *out holds *out_size bytes, to be released with free_bytes.
  Status (*encode_memory)(const char* ext, const std::uint8_t* pixels, std::int32_t w, std::int32_t h, std::int32_t c,
                          const IntAttribute* attrs, std::size_t nattrs, std::uint8_t** out, std::size_t* out_size,
                          char* err, std::size_t err_size);
  void (*free_bytes)(std::uint8_t* bytes);
};

// The one exported symbol (extern "C", named kEntrySymbol): the module's table, never null.
using EntryFn = const Api* (*)();

}  // namespace vtsim::image_abi
