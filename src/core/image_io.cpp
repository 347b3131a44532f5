#include "core/image_io.h"

#include <dlfcn.h>
#include <sys/auxv.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstring>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <system_error>

#include <fmt/format.h>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/input_file.h"

// The module's path in the build tree (CMakeLists.txt sets it on this file only).
#ifndef VTSIM_IMAGE_MODULE_BUILD_PATH
#define VTSIM_IMAGE_MODULE_BUILD_PATH ""
#endif
// Where `cmake --install` puts it: relative to the executable's directory (an install tree moved
// elsewhere) and the absolute path (an engine linking the installed library).
#ifndef VTSIM_IMAGE_MODULE_INSTALL_REL_DIR
#define VTSIM_IMAGE_MODULE_INSTALL_REL_DIR ""
#endif
#ifndef VTSIM_IMAGE_MODULE_INSTALL_PATH
#define VTSIM_IMAGE_MODULE_INSTALL_PATH ""
#endif

namespace vtsim::image_io {

namespace {

namespace abi = image_abi;
namespace fs = std::filesystem;

constexpr const char* kEnvOverride = "VTSIM_IMAGE_MODULE";

struct Module {
  const abi::Api* api = nullptr;
  std::string path;   // the module loaded, or the one that failed to load
  std::string error;  // why it did not load (empty when api is set)
};

std::string dl_error() {
  const char* e = dlerror();
  return e != nullptr ? e : "unknown dynamic loader error";
}

// Directory of the executable, and of the shared object containing this code if that is another
// one (an engine embedding vtsim_lib in a plugin). For the executable itself dladdr reports argv[0],
// which may be relative to some directory; /proc/self/exe is used for it instead.
std::vector<fs::path> binary_dirs() {
  std::vector<fs::path> dirs;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec && exe.is_absolute()) dirs.push_back(exe.parent_path());
  static const int anchor = 0;
  Dl_info self{}, main_program{};
  const auto* phdr = reinterpret_cast<const void*>(getauxval(AT_PHDR));  // in the executable's image
  if (dladdr(&anchor, &self) != 0 && self.dli_fname != nullptr && self.dli_fname[0] == '/' &&
      !(phdr != nullptr && dladdr(phdr, &main_program) != 0 && main_program.dli_fbase == self.dli_fbase)) {
    const fs::path dir = fs::path(self.dli_fname).parent_path();
    if (dirs.empty() || dir != dirs.front()) dirs.push_back(dir);
  }
  return dirs;
}

constexpr const char* kWhy = " (it reads and writes images and PNG/JPEG tiles)";

// `how`: how the path was chosen, for the message ("" or " named by VTSIM_IMAGE_MODULE").
Module open_module(const std::string& path, const std::string& how) {
  const std::string what = "the image module" + how + kWhy;
  Module m;
  m.path = path;
  // RTLD_LOCAL: OpenImageIO's dependencies stay out of the global symbol namespace. Never closed.
  void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) {
    m.error = "cannot load " + what + ": " + dl_error();
    return m;
  }
  dlerror();
  void* sym = dlsym(handle, abi::kEntrySymbol);
  if (sym == nullptr) {
    m.error = "is not " + what + ": " + dl_error();
    return m;
  }
  const abi::Api* api = reinterpret_cast<abi::EntryFn>(sym)();
  if (api == nullptr || api->abi_version != abi::kAbiVersion || api->struct_size < sizeof(abi::Api)) {
    m.error = "is " + what + " with interface version " +
              (api ? std::to_string(api->abi_version) : std::string("?")) + "; this program needs version " +
              std::to_string(abi::kAbiVersion) + " (a module from another build?)";
    return m;
  }
  m.api = api;
  // libopenvdb (a dependency of OpenImageIO's plugins) links log4cplus 2, whose initializer starts
  // a pool of 4 threads for asynchronous appenders; OpenImageIO configures none. Joined here, every
  // process that reads an image has 4 idle foreign threads fewer to carry until exit (the sanitizer
  // builds' tracer crash at exit had another cause: cmake/sanitizer_options.cpp).
  // dlsym on the handle searches the module's whole dependency tree; absent library: nothing to do.
  if (void* stop = dlsym(handle, "_ZN9log4cplus18shutdownThreadPoolEv")) reinterpret_cast<void (*)()>(stop)();
  return m;
}

Module load_module() {
  if (const char* env = std::getenv(kEnvOverride); env != nullptr && env[0] != '\0')
    return open_module(env, std::string(" named by ") + kEnvOverride);
  std::vector<std::string> candidates;
  const auto add = [&candidates](const std::string& c) {
    if (!c.empty() && std::find(candidates.begin(), candidates.end(), c) == candidates.end()) candidates.push_back(c);
  };
  const std::vector<fs::path> dirs = binary_dirs();
  for (const fs::path& dir : dirs) add((dir / abi::kModuleFileName).string());
  if (VTSIM_IMAGE_MODULE_INSTALL_REL_DIR[0] != '\0')
    for (const fs::path& dir : dirs)
      add((dir / VTSIM_IMAGE_MODULE_INSTALL_REL_DIR / abi::kModuleFileName).lexically_normal().string());
  add(VTSIM_IMAGE_MODULE_BUILD_PATH);
  add(VTSIM_IMAGE_MODULE_INSTALL_PATH);
  for (const std::string& c : candidates)
    if (::access(c.c_str(), F_OK) == 0) return open_module(c, "");
  Module m;
  m.path = abi::kModuleFileName;
  m.error = std::string("cannot find the image module") + kWhy + "; looked for";
  for (std::size_t i = 0; i < candidates.size(); ++i) m.error += (i ? ", " : " ") + candidates[i];
  m.error += std::string(". Put it next to the executable or set ") + kEnvOverride + " to its path";
  return m;
}

const Module& module() {
  static const Module m = load_module();  // thread-safe, once per process
  return m;
}

const abi::Api& api() {
  const Module& m = module();
  if (!m.api) throw InputError(m.path, m.error);
  return *m.api;
}

abi::PixelType to_abi(PixelType t) {
  switch (t) {
    case PixelType::u8: return abi::kU8;
    case PixelType::u16: return abi::kU16;
    case PixelType::f32: return abi::kF32;
  }
  return abi::kU8;
}

// Error text from the module: at most this long (OpenImageIO's messages are a line or two).
using ErrorBuf = std::array<char, 4096>;

ImageSpec to_spec(const abi::Spec& s) {
  ImageSpec r;
  r.width = s.width;
  r.height = s.height;
  r.depth = s.depth;
  r.channels = s.nchannels;
  r.is_uint8 = s.is_uint8 != 0;
  r.is_float = s.is_float != 0;
  r.tile_width = s.tile_width;
  r.tile_height = s.tile_height;
  r.tile_depth = s.tile_depth;
  r.format.assign(s.format, strnlen(s.format, sizeof s.format));
  return r;
}

}  // namespace

const std::string& require_module() {
  api();
  return module().path;
}

namespace {

// PNG 1.2 §5.3: a chunk is a 4-byte big-endian length (at most 2^31 − 1), a 4-byte type, the data
// and a 4-byte CRC. libpng allocates and clears a chunk's declared length before reading it, so a
// 298-byte file declaring a 1.6 GB tEXt chunk cost 1.6 GB and 9 s inside OpenImageIO's open (fuzz
// finding). Walks the chunk headers of a `size`-byte image through read(offset, out, n) -> bytes
// read, and says why they cannot be a PNG of that size: a chunk longer than what is left. "" when
// they can, or when the bytes are not a PNG at all (not this check's to judge). Stops at IEND.
template <class Read>
std::string png_chunk_problem(std::uint64_t size, Read&& read) {
  static constexpr std::array<std::uint8_t, 8> kSignature = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  std::array<std::uint8_t, 8> h{};
  if (size < 8 || read(0, h.data(), 8) != 8 || h != kSignature) return "";
  for (std::uint64_t at = 8; at + 8 <= size; ) {
    if (read(at, h.data(), 8) != 8) return "";
    const std::uint32_t length = std::uint32_t{h[0]} << 24 | std::uint32_t{h[1]} << 16 | std::uint32_t{h[2]} << 8 | h[3];
    const bool letters = std::all_of(h.begin() + 4, h.end(), [](std::uint8_t c) { return std::isalpha(c) != 0; });
    if (length > 0x7FFFFFFFu || std::uint64_t{length} + 12 > size - at)
      return fmt::format("PNG chunk {} at byte {} declares {} bytes of data, more than the {} bytes after it "
                         "(damaged or truncated)",
                         letters ? fmt::format("'{}'", std::string(h.begin() + 4, h.end()))
                                 : fmt::format("0x{:02X}{:02X}{:02X}{:02X}", h[4], h[5], h[6], h[7]),
                         at, length, size - at - 8);
    if (std::equal(h.begin() + 4, h.end(), "IEND")) return "";
    at += std::uint64_t{length} + 12;
  }
  return "";
}

// Byte `at` of a `size`-byte image, or -1 past its end (or where read gives nothing), read through
// read(offset, out, n) -> bytes read, 4 KiB at a time; for the header walks below.
template <class Read>
class ByteWindow {
 public:
  ByteWindow(std::uint64_t size, Read& read) : size_(size), read_(read) {}
  int operator()(std::uint64_t at) {
    if (at < at_ || at >= at_ + n_) {
      at_ = at;
      n_ = at < size_ ? read_(at, buf_.data(), static_cast<std::size_t>(std::min<std::uint64_t>(buf_.size(), size_ - at)))
                      : 0;
      if (n_ == 0) return -1;
    }
    return buf_[static_cast<std::size_t>(at - at_)];
  }

 private:
  std::uint64_t size_;
  Read& read_;
  std::array<std::uint8_t, 4096> buf_{};
  std::uint64_t at_ = 0, n_ = 0;
};

// OpenEXR 3.1 sizes a header attribute's value by the size the file declares before reading it: a
// 1,466-byte file declaring a string attribute of ~1 GB made it allocate 2.1 GB (3.8 s; fuzz
// finding). Walks the header(s) (OpenEXR file layout: magic, 4-byte version and flags, then per
// attribute a NUL-terminated name and type and a little-endian int32 size before the value; a
// header ends with an empty name, a multi-part file's list of headers with one more) and refuses
// an attribute whose size is negative or more than the bytes after it. "" when fine, or when not
// OpenEXR or not walkable (OpenEXR's to judge).
template <class Read>
std::string exr_header_problem(std::uint64_t size, Read&& read) {
  ByteWindow<Read> byte(size, read);
  if (byte(0) != 0x76 || byte(1) != 0x2F || byte(2) != 0x31 || byte(3) != 0x01 || byte(5) < 0) return "";
  const bool multipart = (byte(5) & 0x10) != 0;  // version flags bit 12: multi-part
  auto text = [&](std::uint64_t& at) {  // a NUL-terminated name of at most 255 bytes, or "\x01" when not
    std::string t;
    for (int c = byte(at); t.size() < 256; c = byte(at)) {
      if (c < 0) return std::string("\x01");
      ++at;
      if (c == 0) return t;
      t.push_back(static_cast<char>(c));
    }
    return std::string("\x01");
  };
  for (std::uint64_t at = 8;;) {  // headers
    for (;;) {                    // attributes
      const std::uint64_t attribute_at = at;
      const std::string name = text(at);
      if (name == "\x01") return "";
      if (name.empty()) break;
      const std::string type = text(at);
      if (type == "\x01") return "";
      std::uint32_t bits = 0;
      for (int i = 0; i < 4; ++i) {
        const int c = byte(at + static_cast<std::uint64_t>(i));
        if (c < 0) return "";
        bits |= static_cast<std::uint32_t>(c) << (8 * i);
      }
      at += 4;
      const auto declared = static_cast<std::int32_t>(bits);
      if (declared < 0 || static_cast<std::uint64_t>(declared) > size - at)
        return fmt::format("OpenEXR header attribute '{}' ({}) at byte {} declares {} bytes, more than the {} after it "
                           "(damaged or truncated)",
                           name, type, attribute_at, declared, size - at);
      at += static_cast<std::uint64_t>(declared);
    }
    if (!multipart || byte(at) <= 0) return "";  // one header, or the multi-part list's end
  }
}

// OpenImageIO 2.4's JPEG reader decodes an APP13 "Photoshop 3.0" segment's IPTC block with the
// size the block declares, unchecked against the segment: a 1,213-byte JPEG declaring more made it
// copy from past its buffer (heap-buffer-overflow in decode_iptc_iim under ASan; fuzz finding), and
// an APP13 shorter than the header it reads is read past too. Finds the markers before the first
// scan as libjpeg does (jdmarker.c next_marker: bytes up to a 0xFF are skipped, 0xFF fill bytes
// too, FF 00 is not a marker; then for all but RSTn / TEM a big-endian length counting its own 2
// bytes, ITU-T T.81 B.1.1.4) and refuses an APP13 that starts like "Photoshop 3.0\0" but does not
// hold what OpenImageIO reads: the 14-byte name, "8BIM", resource 0x0404, 4 bytes it skips, a
// 2-byte size (26 bytes), then `size` bytes. "" when fine, or when not a JPEG.
template <class Read>
std::string jpeg_segment_problem(std::uint64_t size, Read&& read) {
  ByteWindow<Read> byte(size, read);
  if (byte(0) != 0xFF || byte(1) != 0xD8) return "";
  static constexpr char kName[] = "Photoshop 3.0";  // and its NUL: 14 bytes
  std::array<std::uint8_t, 26> h{};
  for (std::uint64_t at = 2;;) {
    int c = byte(at);
    for (;;) {  // next_marker
      while (c >= 0 && c != 0xFF) c = byte(++at);
      while (c == 0xFF) c = byte(++at);
      if (c != 0) break;
      c = byte(++at);
    }
    if (c < 0) return "";
    const std::uint64_t marker_at = at - 1;
    ++at;  // past the marker byte
    if (c == 0xD9 || c == 0xDA) return "";  // EOI, SOS: no more metadata segments
    if (c == 0x01 || (c >= 0xD0 && c <= 0xD7)) continue;
    const int hi = byte(at), lo = byte(at + 1);
    if (hi < 0 || lo < 0) return "";
    const std::uint32_t length = static_cast<std::uint32_t>(hi << 8 | lo);
    if (c == 0xED) {  // APP13
      const std::uint64_t data = std::min<std::uint64_t>(length < 2 ? 0 : length - 2, size - std::min(size, at + 2));
      std::size_t n = 0;
      for (; n < h.size() && n < data; ++n) h[n] = static_cast<std::uint8_t>(byte(at + 2 + n));
      if (std::memcmp(h.data(), kName, std::min(n, sizeof kName)) == 0) {  // OpenImageIO's strcmp reads on while it matches
        if (n < h.size())
          return fmt::format("JPEG APP13 segment at byte {} holds {} bytes, too few for the Photoshop IPTC header "
                             "(26 bytes; damaged or truncated)",
                             marker_at, data);
        const std::uint32_t iptc = std::uint32_t{h[24]} << 8 | h[25];
        if (std::memcmp(h.data() + 14, "8BIM\x04\x04", 6) == 0 && iptc + 26 > data)
          return fmt::format("JPEG APP13 segment at byte {}: its IPTC block declares {} bytes, more than the {} "
                             "the segment holds after its header (damaged)",
                             marker_at, iptc, data - 26);
      }
    }
    at += length;
  }
}

// What png_chunk_problem, jpeg_segment_problem or exr_header_problem find, by the bytes' signature.
template <class Read>
std::string header_problem(std::uint64_t size, Read&& read) {
  std::string problem = png_chunk_problem(size, read);
  if (problem.empty()) problem = jpeg_segment_problem(size, read);
  if (problem.empty()) problem = exr_header_problem(size, read);
  return problem;
}

}  // namespace

ImageReader ImageReader::open_file(const std::string& path, bool unassociated_alpha) {
  ImageReader r;
  r.api_ = &api();
  try {
    require_regular_file(path);  // a FIFO would block inside the reader's open
  } catch (const InputError& e) {
    r.error_ = e.what();
    return r;
  }
  std::ifstream f(path, std::ios::binary);
  std::error_code ec;
  const std::uint64_t size = fs::file_size(path, ec);
  r.error_ = header_problem(ec ? 0 : size, [&](std::uint64_t at, std::uint8_t* out, std::size_t n) {
    f.seekg(static_cast<std::streamoff>(at));
    f.read(reinterpret_cast<char*>(out), static_cast<std::streamsize>(n));
    const auto got = f.gcount();
    f.clear();
    return static_cast<std::size_t>(got);
  });
  if (!r.error_.empty()) return r;
  ErrorBuf err{};
  abi::Spec spec{};
  if (r.api_->open_file(path.c_str(), unassociated_alpha ? 1 : 0, &r.reader_, &spec, err.data(), err.size()) != abi::kOk) {
    r.reader_ = nullptr;
    r.error_ = err.data();
    return r;
  }
  r.spec_ = to_spec(spec);
  return r;
}

ImageReader ImageReader::open_memory(const char* ext, const std::uint8_t* bytes, std::size_t size) {
  ImageReader r;
  r.api_ = &api();
  r.error_ = header_problem(size, [&](std::uint64_t at, std::uint8_t* out, std::size_t n) {
    n = static_cast<std::size_t>(std::min<std::uint64_t>(n, size - at));
    std::memcpy(out, bytes + at, n);
    return n;
  });
  if (!r.error_.empty()) return r;
  ErrorBuf err{};
  abi::Spec spec{};
  if (r.api_->open_memory(ext, bytes, size, &r.reader_, &spec, err.data(), err.size()) != abi::kOk) {
    r.reader_ = nullptr;
    r.error_ = err.data();
    return r;
  }
  r.spec_ = to_spec(spec);
  return r;
}

ImageReader::ImageReader(ImageReader&& other) noexcept
    : api_(other.api_), reader_(other.reader_), spec_(other.spec_), error_(std::move(other.error_)) {
  other.reader_ = nullptr;
}

ImageReader::~ImageReader() {
  if (reader_ != nullptr) api_->close(reader_);
}

ReadStatus ImageReader::read(int channels, PixelType type, void* out, int threads) {
  if (reader_ == nullptr) return not_open();
  ErrorBuf err{};
  return finish_read(api_->read(reader_, channels, to_abi(type), out, threads, err.data(), err.size()), err.data());
}

ReadStatus ImageReader::read_rows(int y0, int y1, int channels, PixelType type, void* out, int threads) {
  if (reader_ == nullptr) return not_open();
  ErrorBuf err{};
  return finish_read(api_->read_rows(reader_, y0, y1, channels, to_abi(type), out, threads, err.data(), err.size()),
                     err.data());
}

ReadStatus ImageReader::not_open() {
  error_ = "image is not open";
  return ReadStatus::failed;
}

ReadStatus ImageReader::finish_read(std::int32_t status, const char* err) {
  error_ = err;
  if (status == abi::kOk) return ReadStatus::ok;
  // OpenImageIO's PNM reader fails on missing pixel data without a message.
  if (error_.empty()) error_ = "the reader gave no reason (truncated or damaged pixel data?)";
  return status == abi::kOkWithError ? ReadStatus::ok_with_error : ReadStatus::failed;
}

WriteResult write_file(const std::string& path, int width, int height, int channels, PixelType type,
                       const void* pixels, bool unassociated_alpha) {
  const abi::Api& a = api();
  ErrorBuf err{};
  WriteResult r;
  try {
    // Whole or not at all: the module writes a temporary that keeps the extension (the format
    // comes from it), renamed over `path` once the image is written.
    AtomicFile out(path, /*keep_extension=*/true);
    if (out.temp_path() != out.path()) out.close_fd();
    const abi::Status s = a.write_file(out.temp_path().c_str(), width, height, channels, to_abi(type), pixels,
                                       unassociated_alpha ? 1 : 0, err.data(), err.size());
    r.status = s == abi::kOk ? WriteStatus::ok : s == abi::kCannotCreate ? WriteStatus::cannot_create : WriteStatus::failed;
    r.error = err.data();
    if (r.status == WriteStatus::ok) out.commit();
  } catch (const InputError& e) {
    r.status = WriteStatus::failed;
    r.error = e.what();
  }
  return r;
}

bool encode_memory(const char* ext, const std::uint8_t* pixels, int width, int height, int channels,
                   const std::vector<std::pair<std::string, int>>& int_attrs, std::vector<std::uint8_t>& out,
                   std::string& error) {
  const abi::Api& a = api();
  std::vector<abi::IntAttribute> attrs;
  attrs.reserve(int_attrs.size());
  for (const auto& [name, value] : int_attrs) attrs.push_back({name.c_str(), value});
  ErrorBuf err{};
  std::uint8_t* bytes = nullptr;
  std::size_t size = 0;
  if (a.encode_memory(ext, pixels, width, height, channels, attrs.data(), attrs.size(), &bytes, &size, err.data(),
                      err.size()) != abi::kOk) {
    error = err.data();
    return false;
  }
  const std::unique_ptr<std::uint8_t, void (*)(std::uint8_t*)> owned(bytes, a.free_bytes);
  out.assign(bytes, bytes + size);
  return true;
}

// Bytes a format's reader (OpenImageIO 2.4 and its libraries) holds beyond the rows it returns,
// per pixel of the whole image. Peak RSS of `vtsim store build F --levels 1 --codec raw --threads
// 1` on 4096 × 4096 RGB 8-bit noise, against the TIFF's 201 MB (docs/store-format.md §8):
// - tiff, openexr, hdr, bmp, sgi: +0–5 MB, rows (or tiles) at a time: nothing;
// - png: the same, but an interlaced PNG is read whole in the file's format: one copy;
// - pnm, targa: +42 MB, the image in the file's format: one copy;
// - jpeg: +0 MB baseline, +42 MB progressive (libjpeg keeps a 16-bit coefficient per component
//   sample of the whole image, up to 2 bytes a channel with no chroma subsampling);
// - jpeg2000: +197 MB, OpenJPEG's 32-bit plane per component: 4 bytes a channel (201 MB);
// - webp: +56 MB, libwebp decodes to RGBA8: 4 bytes a pixel (67 MB);
// - any other reader (not measured): a float or double RGBA copy, 8 bytes × max(channels, 4).
// The interlaced / progressive cases are counted for every PNG and JPEG: the header the check
// reads does not say, and over-counting only refuses images within ~2× of the limit.
double whole_image_decode_bytes(const ImageSpec& s) {
  const double pixels = static_cast<double>(s.width) * static_cast<double>(s.height) *
                        static_cast<double>(std::max(s.depth, 1));
  const double channels = static_cast<double>(s.channels);
  const double native = s.is_uint8 ? 1.0 : s.is_float ? 8.0 : 4.0;  // as read_scratch_bytes
  const std::string& f = s.format;
  if (f == "tiff" || f == "openexr" || f == "hdr" || f == "bmp" || f == "sgi") return 0.0;
  if (f == "png" || f == "pnm" || f == "targa") return pixels * channels * native;
  if (f == "jpeg") return pixels * channels * 2.0;
  if (f == "jpeg2000") return pixels * channels * 4.0;
  if (f == "webp") return pixels * 4.0;
  return pixels * std::max(channels, 4.0) * 8.0;
}

void require_read_memory(const std::string& path, const ImageSpec& spec, double out_bytes, std::uint64_t max_bytes) {
  const double need = out_bytes + read_scratch_bytes(spec);
  if (need > static_cast<double>(max_bytes))
    throw InputError(path, fmt::format("{}x{} pixels x {} channel(s){} need {:.1f} MiB to read, more than the {:.1f} MiB "
                                       "available for it",
                                       spec.width, spec.height, spec.channels,
                                       spec.tile_width > 0 ? fmt::format(" in {}x{} tiles", spec.tile_width, spec.tile_height)
                                                           : std::string(),
                                       need / 1048576.0, static_cast<double>(max_bytes) / 1048576.0));
}

}  // namespace vtsim::image_io
