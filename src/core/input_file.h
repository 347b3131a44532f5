#pragma once
// Untrusted input paths: reading a FIFO blocks until someone writes to it, /dev/zero never ends
// and a directory reads as nothing. Readers check the descriptor they read from, not the path:
// the path cannot change between the check and the read.
#include <sys/stat.h>

#include <cstdint>
#include <string>

namespace vtsim {

// Why a file of this st_mode is refused as input (every reader words it the same).
inline const char* not_regular_reason(mode_t mode) {
  return S_ISDIR(mode) ? "is a directory, not a file" : "not a regular file (a FIFO, socket or device)";
}

// An open regular file, closed by the destructor unless released.
class RegularFile {
 public:
  RegularFile(int fd, std::uint64_t size) : fd_(fd), size_(size) {}
  ~RegularFile();
  RegularFile(RegularFile&& o) noexcept : fd_(o.release()), size_(o.size_) {}
  RegularFile& operator=(RegularFile&&) = delete;
  RegularFile(const RegularFile&) = delete;
  RegularFile& operator=(const RegularFile&) = delete;
  int fd() const { return fd_; }
  std::uint64_t size() const { return size_; }  // bytes, at the open
  int release() {  // the caller owns the descriptor from now on
    const int fd = fd_;
    fd_ = -1;
    return fd;
  }

 private:
  int fd_ = -1;
  std::uint64_t size_ = 0;
};

// Opens path read-only, close-on-exec and without becoming a controlling terminal, with
// O_NONBLOCK so that a FIFO without a writer cannot block the open, then fstat()s the descriptor:
// anything but a regular file is refused (not_regular_reason). The descriptor is returned in
// blocking mode. Throws InputError(path, ...) ("cannot open: <errno text>"); nothing leaks.
RegularFile open_regular_file(const std::string& path);

// The whole of a regular file (open_regular_file) of at most max_bytes, refused before reading
// when larger: InputError(path, "<size> bytes, larger than <limit>: <what_if_larger>"). Reads to
// the end of file, not to the size fstat gave (a /proc file says 0), and never more than
// max_bytes + 1 bytes. Read errors throw InputError(path, "read failed: ...").
std::string read_regular_file(const std::string& path, std::uint64_t max_bytes, const std::string& what_if_larger);

// For readers that must hand a path to a library which opens it itself (the image module): a
// stat() of the path, same messages. A window remains between this check and the library's open.
void require_regular_file(const std::string& path);

}  // namespace vtsim
