#include "stream/store/aligned_io.h"

#include "core/input_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <new>
#include <system_error>
#include <utility>

#include "core/error.h"

namespace vtsim {

AlignedBuffer::AlignedBuffer(std::size_t bytes) { reserve(bytes); }
AlignedBuffer::~AlignedBuffer() { std::free(data_); }
AlignedBuffer::AlignedBuffer(AlignedBuffer&& o) noexcept
    : data_(std::exchange(o.data_, nullptr)), size_(std::exchange(o.size_, 0)) {}
AlignedBuffer& AlignedBuffer::operator=(AlignedBuffer&& o) noexcept {
  if (this != &o) {
    std::free(data_);
    data_ = std::exchange(o.data_, nullptr);
    size_ = std::exchange(o.size_, 0);
  }
  return *this;
}
void AlignedBuffer::reserve(std::size_t bytes) {
  if (bytes <= size_) return;
  void* p = nullptr;
  const std::size_t rounded = (bytes + kAlignment - 1) / kAlignment * kAlignment;
  if (posix_memalign(&p, kAlignment, rounded) != 0) throw std::bad_alloc();
  std::memset(p, 0, rounded);
  std::free(data_);
  data_ = static_cast<std::uint8_t*>(p);
  size_ = rounded;
}

ReadFile::~ReadFile() {
  if (fd_ >= 0) ::close(fd_);
}
ReadFile::ReadFile(ReadFile&& o) noexcept
    : fd_(std::exchange(o.fd_, -1)), direct_(o.direct_), path_(std::move(o.path_)) {}
ReadFile& ReadFile::operator=(ReadFile&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(o.fd_, -1);
    direct_ = o.direct_;
    path_ = std::move(o.path_);
  }
  return *this;
}

std::uint64_t ReadFile::size() const {
  struct stat st {};
  if (::fstat(fd_, &st) != 0) throw std::system_error(errno, std::generic_category(), "fstat " + path_);
  return static_cast<std::uint64_t>(st.st_size);
}

std::size_t ReadFile::pread_full(void* buf, std::size_t bytes, std::uint64_t offset) const {
  std::size_t done = 0;
  auto* p = static_cast<std::uint8_t*>(buf);
  while (done < bytes) {
    const ssize_t r = ::pread(fd_, p + done, bytes - done, static_cast<off_t>(offset + done));
    if (r < 0) {
      if (errno == EINTR) continue;
      throw std::system_error(errno, std::generic_category(), "read " + path_ + " at offset " + std::to_string(offset + done));
    }
    if (r == 0) break;  // end of file
    done += static_cast<std::size_t>(r);
  }
  return done;
}

DirectOpen open_for_read(const std::string& path, bool want_direct) {
  // One open, checked by descriptor (open_regular_file); O_DIRECT is then switched on with fcntl
  // on that descriptor (Linux allows it). A filesystem without direct IO says EINVAL there, or —
  // where the switch only takes effect at the next read (overlayfs) — at the probe read.
  RegularFile rf = open_regular_file(path);
  DirectOpen result;
  bool direct = false;
  if (want_direct) {
    AlignedBuffer probe(AlignedBuffer::kAlignment);
    const int flags = ::fcntl(rf.fd(), F_GETFL);
    if (flags >= 0 && ::fcntl(rf.fd(), F_SETFL, flags | O_DIRECT) == 0) {
      ssize_t r;
      do r = ::pread(rf.fd(), probe.data(), probe.size(), 0);
      while (r < 0 && errno == EINTR);
      if (r >= 0) {
        direct = true;
      } else {
        result.warning = path + ": the filesystem refuses O_DIRECT reads (" + std::strerror(errno) +
                         "); reading through the page cache instead";
        if (::fcntl(rf.fd(), F_SETFL, flags) != 0)
          throw InputError(path, std::string("cannot switch O_DIRECT off: ") + std::strerror(errno));
      }
    } else if (errno == EINVAL) {
      result.warning = path + ": the filesystem does not support O_DIRECT; reading through the page cache instead";
    } else {
      result.warning = path + ": O_DIRECT failed (" + std::string(std::strerror(errno)) +
                       "); reading through the page cache instead";
    }
  }
  std::string owned_path = path;
  result.file = ReadFile(rf.release(), direct, std::move(owned_path));  // nothing throws from here
  return result;
}

}  // namespace vtsim
