#include "core/input_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "core/error.h"

namespace vtsim {

namespace {

[[noreturn]] void fail_closing(int fd, const std::string& path, const std::string& why) {
  ::close(fd);
  throw InputError(path, why);
}

std::string size_text(std::uint64_t bytes) {
  if (bytes >= (1u << 20) && bytes % (1u << 20) == 0) return std::to_string(bytes >> 20) + " MiB";
  return std::to_string(bytes) + " bytes";
}

}  // namespace

RegularFile open_regular_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0) fail_closing(fd, path, std::string("cannot stat: ") + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) fail_closing(fd, path, not_regular_reason(st.st_mode));
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags < 0 || ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK) != 0)
    fail_closing(fd, path, std::string("cannot open: ") + std::strerror(errno));
  return {fd, static_cast<std::uint64_t>(st.st_size)};
}

std::string read_regular_file(const std::string& path, std::uint64_t max_bytes, const std::string& what_if_larger) {
  const RegularFile f = open_regular_file(path);
  if (f.size > max_bytes)
    fail_closing(f.fd, path, std::to_string(f.size) + " bytes, larger than " + size_text(max_bytes) + ": " + what_if_larger);
  std::string text;
  // The size at the open is a hint: the file may grow or shrink while it is read, and only
  // max_bytes + 1 bytes are ever read (one more to tell "larger").
  text.resize(static_cast<std::size_t>(f.size));
  std::size_t done = 0;
  for (;;) {
    if (done == text.size()) {
      if (text.size() > max_bytes) break;
      text.resize(static_cast<std::size_t>(std::min<std::uint64_t>(max_bytes + 1, text.size() + 65536)));
    }
    const ssize_t r = ::read(f.fd, text.data() + done, text.size() - done);
    if (r < 0) {
      if (errno == EINTR) continue;
      fail_closing(f.fd, path, std::string("read failed: ") + std::strerror(errno));
    }
    if (r == 0) break;
    done += static_cast<std::size_t>(r);
  }
  ::close(f.fd);
  text.resize(done);
  if (text.size() > max_bytes)
    throw InputError(path, "grew past " + size_text(max_bytes) + " while read: " + what_if_larger);
  return text;
}

void require_regular_file(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) throw InputError(path, not_regular_reason(st.st_mode));
}

}  // namespace vtsim
