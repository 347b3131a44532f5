#pragma once
// Image files and in-memory PNG / JPEG, through the image module (libvtsim_image.so, OpenImageIO),
// which is loaded with dlopen on first use: a process that reads and writes no image never loads
// OpenImageIO and its ~250 shared libraries (~0.5 s of CPU at start-up).
//
// Where the module is looked up, first hit wins:
//   1. $VTSIM_IMAGE_MODULE, if set and non-empty (only there);
//   2. next to the executable (/proc/self/exe), then next to the shared object that contains
//      vtsim_lib if that is not the executable (dladdr): install the module beside the binary;
//   3. the path it was built at (the build tree), compiled in.
// If it cannot be loaded, every call below throws InputError naming the module path and the
// loader's reason (dlerror); the first attempt's outcome is kept for the life of the process.
//
// Thread-safety: the module is loaded once (thread-safe); the functions may be called from many
// threads at once, each on its own ImageReader.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/image_module_abi.h"

namespace vtsim::image_io {

enum class PixelType { u8, u16, f32 };

struct ImageSpec {
  int width = 0, height = 0, depth = 0, channels = 0;
  bool is_uint8 = false;  // the file stores 8-bit unsigned pixels
  bool is_float = false;  // ... floating-point pixels (half, float, double)
  int tile_width = 0, tile_height = 0, tile_depth = 0;  // the file's tiles; 0 for scanline files
  std::string format;  // OpenImageIO's reader: "tiff", "openexr", "png", "jpeg", "jpeg2000", ...
};

// Bytes OpenImageIO itself may allocate while read() or read_rows() converts the image to the
// requested type (ImageInput::read_scanlines / read_tiles, OpenImageIO 2.4), an upper bound in
// double (it can pass 2^64):
// - scanline files: read_scanlines' strip of ~64 MiB rounded up to whole chunks of at least 64
//   rows (256 with a larger oiio:read_chunk) of every channel in the file's own format, however
//   few rows the image has — a 52-byte PBM claiming 44,444,444 × 2 pixels made it allocate 11 GB
//   (fuzz finding);
// - tiled files: read_tiles reads a row of tiles at a time into one buffer, plus a whole tile for
//   partial edge tiles, one in read_native_tiles and the format's own decode buffer (counted as 4
//   tiles), all sized by the tile in the header, not the image — a 12 KB TIFF of 64 × 64 pixels
//   claiming 65,520 × 65,520 tiles took 24 GB before the OOM killer stopped it;
// - plus, for readers that hold more than rows at a time, whole_image_decode_bytes.
double whole_image_decode_bytes(const ImageSpec& s);
inline double read_scratch_bytes(const ImageSpec& s) {
  const double value_bytes = s.is_uint8 ? 1.0 : s.is_float ? 8.0 : 4.0;
  const double pixel = static_cast<double>(s.channels) * value_bytes;
  const double whole = whole_image_decode_bytes(s);
  if (s.tile_width > 0 && s.tile_height > 0) {
    const double tile = static_cast<double>(s.tile_width) * static_cast<double>(s.tile_height) *
                        static_cast<double>(std::max(s.tile_depth, 1)) * pixel;
    const double across = std::ceil(static_cast<double>(s.width) / static_cast<double>(s.tile_width));
    return (across + 4.0) * tile + whole;
  }
  const double row = static_cast<double>(s.width) * pixel;
  return std::max(static_cast<double>(1 << 26) + 64.0 * row, 256.0 * row) + whole;
}

// Rows in one chunk of ImageReader::read_chunked for rows of row_bytes: about chunk_bytes, at
// least one row (one row of tiles for a tiled file), at most the image's height.
inline std::int64_t chunk_rows(const ImageSpec& s, std::size_t row_bytes, std::size_t chunk_bytes) {
  std::int64_t rows = std::max<std::int64_t>(1, static_cast<std::int64_t>(chunk_bytes / std::max<std::size_t>(row_bytes, 1)));
  if (s.tile_width > 0 && s.tile_height > 0) rows = std::max<std::int64_t>(1, rows / s.tile_height) * s.tile_height;
  return std::min<std::int64_t>(rows, s.height);
}

// Bytes one chunk of read_chunked costs, for require_read_memory's out_bytes: the chunk, and for a
// tiled file twice more — OpenImageIO's TIFF reader decodes deflate tiles in parallel with a
// compressed and an uncompressed buffer for every tile of the request (measured: a 16 MiB chunk of
// 8-bit zip tiles grew the process by 48 MiB with 8 reader threads).
inline double chunk_read_bytes(const ImageSpec& s, std::size_t row_bytes, std::size_t chunk_bytes) {
  const double chunk = static_cast<double>(chunk_rows(s, row_bytes, chunk_bytes)) * static_cast<double>(row_bytes);
  return s.tile_width > 0 ? 3.0 * chunk : chunk;
}

// Call before allocating the buffers a read of `spec` needs: throws InputError(path, ...) when
// those (out_bytes, the caller's) plus read_scratch_bytes exceed max_bytes, naming the size.
void require_read_memory(const std::string& path, const ImageSpec& spec, double out_bytes, std::uint64_t max_bytes);

enum class ReadStatus {
  ok,
  failed,         // error() says why (may be empty)
  ok_with_error,  // pixels read, but the reader reports an error (damaged data); error() has it
};

// What read_chunked does at a chunk the reader reports damaged (ok_with_error). libjpeg and libtiff
// fill what they cannot decode (a truncated JPEG's missing rows come back grey) and say so only as
// a pending error, so a caller that must not build on invented pixels stops there.
enum class OnDamage {
  stop,     // return ok_with_error at once; the sink never sees the damaged chunk
  read_on,  // hand the chunk to the sink and go on; ok_with_error at the end
};

// An image open for reading: a file, or a PNG / JPEG held in memory.
class ImageReader {
 public:
  // Opens `path` (first subimage); unassociated_alpha keeps alpha as stored. A file that does not
  // open gives !ok() and error() (OpenImageIO's message, possibly empty).
  static ImageReader open_file(const std::string& path, bool unassociated_alpha);
  // Opens bytes[0, size) as a file of format `ext` ("png", "jpg"), alpha unassociated. The bytes
  // must outlive the reader.
  static ImageReader open_memory(const char* ext, const std::uint8_t* bytes, std::size_t size);

  ImageReader(ImageReader&& other) noexcept;
  ImageReader& operator=(ImageReader&&) = delete;
  ImageReader(const ImageReader&) = delete;
  ImageReader& operator=(const ImageReader&) = delete;
  ~ImageReader();

  bool ok() const { return reader_ != nullptr; }
  explicit operator bool() const { return ok(); }
  const ImageSpec& spec() const { return spec_; }
  const std::string& error() const { return error_; }
  // Reads channels [0, channels) of the whole image as `type` into out (width*height*channels
  // values). threads: the reader's own worker threads (0: OpenImageIO's default; the decode pool
  // passes 1). Requires ok().
  ReadStatus read(int channels, PixelType type, void* out, int threads = 0);
  // Reads rows [y0, y1) the same way into out (width*(y1-y0)*channels values). A tiled file needs
  // y0 a multiple of spec().tile_height, and y1 too unless it is the height.
  ReadStatus read_rows(int y0, int y1, int channels, PixelType type, void* out, int threads = 0);
  // Reads the whole image as T (std::uint8_t, std::uint16_t or float) in chunks of whole rows —
  // whole rows of tiles for a tiled file — of about chunk_bytes, calling sink(y0, y1, values) for
  // rows [y0, y1) in order (channels values a pixel). It holds one chunk, so a header claiming
  // more rows than the file has fails at the first chunk it lacks, before the caller has grown its
  // image past the rows read. Stops at the first chunk that fails (failed). At the first chunk the
  // reader reports damaged: on_damage (ok_with_error either way; error() keeps the first message).
  template <class T, class Sink>
  ReadStatus read_chunked(int channels, std::size_t chunk_bytes, OnDamage on_damage, Sink&& sink);

 private:
  ImageReader() = default;
  ReadStatus not_open();
  ReadStatus finish_read(std::int32_t status, const char* err);  // status: an image_abi::Status
  const image_abi::Api* api_ = nullptr;
  image_abi::Reader* reader_ = nullptr;
  ImageSpec spec_;
  std::string error_;
};

template <class T, class Sink>
ReadStatus ImageReader::read_chunked(int channels, std::size_t chunk_bytes, OnDamage on_damage, Sink&& sink) {
  static_assert(std::is_same_v<T, std::uint8_t> || std::is_same_v<T, std::uint16_t> || std::is_same_v<T, float>);
  constexpr PixelType type = std::is_same_v<T, std::uint8_t>    ? PixelType::u8
                             : std::is_same_v<T, std::uint16_t> ? PixelType::u16
                                                                : PixelType::f32;
  const std::size_t row_values = static_cast<std::size_t>(spec_.width) * static_cast<std::size_t>(channels);
  const std::int64_t rows = chunk_rows(spec_, row_values * sizeof(T), chunk_bytes);
  std::vector<T> buf(static_cast<std::size_t>(rows) * row_values);
  ReadStatus result = ReadStatus::ok;
  std::string damage;
  for (std::int64_t y = 0; y < spec_.height; y += rows) {
    const std::int64_t y1 = std::min<std::int64_t>(spec_.height, y + rows);
    const ReadStatus s = read_rows(static_cast<int>(y), static_cast<int>(y1), channels, type, buf.data());
    if (s == ReadStatus::failed) return s;
    if (s == ReadStatus::ok_with_error && on_damage == OnDamage::stop) return s;
    if (s == ReadStatus::ok_with_error && result == ReadStatus::ok) {
      result = s;
      damage = error_;
    }
    sink(static_cast<int>(y), static_cast<int>(y1), static_cast<const T*>(buf.data()));
  }
  if (result == ReadStatus::ok_with_error) error_ = damage;
  return result;
}

enum class WriteStatus {
  ok,
  cannot_create,  // no writer for this file type (error: why)
  failed,         // opening, writing or closing failed (error: why)
};
struct WriteResult {
  WriteStatus status = WriteStatus::ok;
  std::string error;
};

// Writes a width x height x channels image of `type` (row-major, interleaved) to `path`; the format
// comes from the extension. unassociated_alpha: the alpha channel is not premultiplied in. Whole or
// not at all (core/atomic_file.h): a failed write leaves an existing `path` as it was.
WriteResult write_file(const std::string& path, int width, int height, int channels, PixelType type,
                       const void* pixels, bool unassociated_alpha);

// Encodes an 8-bit image as a file of format `ext` ("png", "jpg") in memory, with integer attributes
// on the output spec ("png:compressionLevel", "CompressionQuality"). Returns false and sets error
// when the writer fails.
bool encode_memory(const char* ext, const std::uint8_t* pixels, int width, int height, int channels,
                   const std::vector<std::pair<std::string, int>>& int_attrs, std::vector<std::uint8_t>& out,
                   std::string& error);

// Loads the module now if it is not loaded yet; throws InputError if it cannot be. Returns its path.
const std::string& require_module();

}  // namespace vtsim::image_io
