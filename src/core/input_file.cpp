#include "core/input_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "core/error.h"

namespace vtsim {

namespace {

std::string size_text(std::uint64_t bytes) {
  if (bytes >= (1u << 20) && bytes % (1u << 20) == 0) return std::to_string(bytes >> 20) + " MiB";
  return std::to_string(bytes) + " bytes";
}

}  // namespace

RegularFile::~RegularFile() {
  if (fd_ >= 0) ::close(fd_);
}

RegularFile open_regular_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  RegularFile f(fd, 0);
  struct stat st {};
  if (::fstat(fd, &st) != 0) throw InputError(path, std::string("cannot stat: ") + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) throw InputError(path, not_regular_reason(st.st_mode));
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags < 0 || ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK) != 0)
    throw InputError(path, std::string("cannot clear O_NONBLOCK: ") + std::strerror(errno));
  return RegularFile(f.release(), static_cast<std::uint64_t>(st.st_size));
}

std::string read_regular_file(const std::string& path, std::uint64_t max_bytes, const std::string& what_if_larger) {
  const RegularFile f = open_regular_file(path);
  if (f.size() > max_bytes)
    throw InputError(path, std::to_string(f.size()) + " bytes, larger than " + size_text(max_bytes) + ": " + what_if_larger);
  // One byte beyond the size fstat gave: a file read to its end then needs no second allocation
  // (the read of 0 bytes says so); one that grew, or a /proc file that says 0, grows 64 KiB at a
  // time up to max_bytes + 1 (one more than allowed, to tell "larger").
  std::string text(static_cast<std::size_t>(f.size() + 1), '\0');
  std::size_t done = 0;
  for (;;) {
    if (done == text.size()) {
      if (text.size() > max_bytes) break;
      text.resize(static_cast<std::size_t>(std::min<std::uint64_t>(max_bytes + 1, text.size() + 65536)));
    }
    const ssize_t r = ::read(f.fd(), text.data() + done, text.size() - done);
    if (r < 0) {
      if (errno == EINTR) continue;
      throw InputError(path, std::string("read failed: ") + std::strerror(errno));
    }
    if (r == 0) break;
    done += static_cast<std::size_t>(r);
  }
  if (done > max_bytes) throw InputError(path, "grew past " + size_text(max_bytes) + " while read: " + what_if_larger);
  text.resize(done);
  return text;
}

void require_regular_file(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) throw InputError(path, not_regular_reason(st.st_mode));
}

}  // namespace vtsim
