#pragma once
// Building blocks for unbuffered reads (Yao 2007 §4-3): a 4 KiB-aligned buffer and a file opened
// with O_DIRECT where the filesystem accepts it. The IO pool reads tile records with pread into
// AlignedBuffers; TileStore's offsets and read sizes are multiples of 4096, so every read is legal
// under O_DIRECT.
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>

namespace vtsim {

// A heap buffer whose address is a multiple of 4096 (posix_memalign), zero-initialised.
// Move-only; size 0 holds no memory. Not thread-safe to resize while another thread reads it.
class AlignedBuffer {
 public:
  static constexpr std::size_t kAlignment = 4096;
  AlignedBuffer() = default;
  explicit AlignedBuffer(std::size_t bytes);
  ~AlignedBuffer();
  AlignedBuffer(AlignedBuffer&& o) noexcept;
  AlignedBuffer& operator=(AlignedBuffer&& o) noexcept;
  AlignedBuffer(const AlignedBuffer&) = delete;
  AlignedBuffer& operator=(const AlignedBuffer&) = delete;

  // Grows (never shrinks) to at least `bytes`; contents are not kept.
  void reserve(std::size_t bytes);
  std::uint8_t* data() { return data_; }
  const std::uint8_t* data() const { return data_; }
  std::size_t size() const { return size_; }

 private:
  std::uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
};

// A read-only file descriptor, closed on destruction. Move-only.
class ReadFile {
 public:
  ReadFile() = default;
  ReadFile(int fd, bool direct, std::string path) : fd_(fd), direct_(direct), path_(std::move(path)) {}
  ~ReadFile();
  ReadFile(ReadFile&& o) noexcept;
  ReadFile& operator=(ReadFile&& o) noexcept;
  ReadFile(const ReadFile&) = delete;
  ReadFile& operator=(const ReadFile&) = delete;

  int fd() const { return fd_; }
  bool direct() const { return direct_; }  // opened with O_DIRECT and a probe read succeeded
  const std::string& path() const { return path_; }
  std::uint64_t size() const;              // bytes (fstat)

  // Reads exactly `bytes` at `offset` (retrying on EINTR and short reads) into `buf`; with
  // direct(), buf, offset and bytes must be multiples of 4096. Returns the bytes read (< bytes
  // only at end of file); throws std::system_error on an IO error (EIO...).
  std::size_t pread_full(void* buf, std::size_t bytes, std::uint64_t offset) const;

 private:
  int fd_ = -1;
  bool direct_ = false;
  std::string path_;
};

struct DirectOpen {
  ReadFile file;
  std::string warning;  // empty when O_DIRECT works; else why it fell back to buffered reads
};

// Opens `path` once (open_regular_file: a FIFO, device or directory is refused) and, when
// `want_direct`, switches O_DIRECT on for the descriptor with fcntl and probes 4096 bytes at
// offset 0. Where the filesystem refuses it (EINVAL at the switch — procfs, tmpfs before 6.6 — or
// at the probe — overlayfs), O_DIRECT is switched off again and `warning` says why. Throws
// InputError naming the path if the file cannot be opened at all.
DirectOpen open_for_read(const std::string& path, bool want_direct);

}  // namespace vtsim
