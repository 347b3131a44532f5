// Outputs written whole or not at all: temporary file beside the target, then rename (atomic_file.h).
#include "core/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <climits>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include "core/error.h"

namespace vtsim {

namespace {

std::string atomic_errno_text() { return std::strerror(errno); }

// Six characters for a temporary's name: distinct across threads (the counter) and processes (the
// pid and the clock); O_EXCL settles the rest.
std::string atomic_suffix() {
  static std::atomic<std::uint64_t> counter{0};
  std::uint64_t x = counter.fetch_add(1, std::memory_order_relaxed) * 0x9e3779b97f4a7c15ull;
  x ^= static_cast<std::uint64_t>(::getpid()) << 32;
  x ^= static_cast<std::uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count());
  x ^= x >> 31;  // splitmix64's finaliser
  x *= 0xbf58476d1ce4e5b9ull;
  x ^= x >> 29;
  static constexpr char kChars[] = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789";
  std::string s(6, 'a');
  for (char& c : s) {
    c = kChars[x % 62];
    x /= 62;
  }
  return s;
}

void atomic_write_all(int fd, const char* p, std::size_t n, const std::string& where) {
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) throw InputError(where, "write failed: " + atomic_errno_text());
    p += w;
    n -= static_cast<std::size_t>(w);
  }
}

}  // namespace

AtomicFile::AtomicFile(const std::string& path, bool keep_extension) : path_(path) {
  namespace fs = std::filesystem;
  // A symbolic link is written through (its target replaced, the link kept); a device or FIFO
  // (/dev/null, a pipe) is written in place: there is nothing to keep and no rename to make.
  struct stat st{};
  if (::lstat(path.c_str(), &st) == 0 && S_ISLNK(st.st_mode)) {
    if (char* real = ::realpath(path.c_str(), nullptr)) {
      path_ = real;
      std::free(real);
    }
  }
  if (::stat(path_.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
    if (S_ISDIR(st.st_mode)) throw InputError(path, "is a directory; give a file name");
    fd_ = ::open(path_.c_str(), O_WRONLY | O_CLOEXEC | O_NOCTTY);
    if (fd_ < 0) throw InputError(path, "cannot open for writing: " + atomic_errno_text());
    temp_ = path_;
    return;
  }
  const fs::path target(path_);
  const std::string dir = target.has_parent_path() ? target.parent_path().string() : std::string(".");
  const std::string name = target.filename().string();
  const std::string ext = keep_extension ? target.extension().string() : std::string();
  for (int attempt = 0; attempt < 100; ++attempt) {
    std::string t = dir + "/." + name + ".tmp-" + atomic_suffix() + ext;
    fd_ = ::open(t.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOCTTY, 0666);
    if (fd_ >= 0) {
      temp_ = std::move(t);
      return;
    }
    if (errno != EEXIST) break;
  }
  throw InputError(path, "cannot create a temporary file in " + dir + ": " + atomic_errno_text());
}

AtomicFile::~AtomicFile() {
  if (fd_ >= 0) ::close(fd_);
  if (!committed_ && temp_ != path_ && !temp_.empty()) ::unlink(temp_.c_str());
}

void AtomicFile::write(std::string_view bytes) {
  if (fd_ < 0) throw InputError(path_, "write after close");
  atomic_write_all(fd_, bytes.data(), bytes.size(), path_);
}

void AtomicFile::close_fd() {
  if (fd_ < 0) return;
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0 && errno != EINTR) throw InputError(path_, "write failed: " + atomic_errno_text());
}

void AtomicFile::commit() {
  if (committed_) return;
  if (temp_ == path_) {  // a device or FIFO, written in place
    close_fd();
    committed_ = true;
    return;
  }
  if (fd_ < 0) {  // the writer wrote by name: open it again to sync what it wrote
    fd_ = ::open(temp_.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0) throw InputError(path_, "cannot reopen " + temp_ + ": " + atomic_errno_text());
  }
  if (::fsync(fd_) != 0 && errno != EINVAL) throw InputError(path_, "fsync failed: " + atomic_errno_text());
  close_fd();
  if (::rename(temp_.c_str(), path_.c_str()) != 0)
    throw InputError(path_, "cannot rename " + temp_ + " into place: " + atomic_errno_text());
  committed_ = true;
  const std::filesystem::path target(path_);
  const std::string dir = target.has_parent_path() ? target.parent_path().string() : std::string(".");
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {  // make the rename itself durable
    ::fsync(dfd);
    ::close(dfd);
  }
}

void check_output_dir(const std::string& flag, const std::string& dir) {
  namespace fs = std::filesystem;
  if (dir.empty()) throw InputError(flag, "an empty directory name");
  std::error_code ec;
  const fs::file_status st = fs::status(dir, ec);
  if (fs::exists(st)) {
    if (!fs::is_directory(st)) throw InputError(flag, "'" + dir + "' exists and is not a directory");
    if (::access(dir.c_str(), W_OK | X_OK) != 0) throw InputError(flag, "the directory '" + dir + "' is not writable");
    return;
  }
  fs::path p(dir);
  while (p.has_relative_path() && p.filename().empty()) p = p.parent_path();  // "a/b/" -> "a/b"
  const std::string parent = p.has_parent_path() ? p.parent_path().string() : std::string(".");
  if (!fs::is_directory(parent, ec))
    throw InputError(flag, "'" + dir + "': the directory '" + parent + "' does not exist (create it first: only the last "
                           "level of an output directory is created)");
  if (::access(parent.c_str(), W_OK | X_OK) != 0)
    throw InputError(flag, "'" + dir + "': the directory '" + parent + "' is not writable");
}

void make_output_dir(const std::string& flag, const std::string& dir) {
  check_output_dir(flag, dir);
  std::error_code ec;
  std::filesystem::create_directory(dir, ec);
  if (ec && !std::filesystem::is_directory(dir)) throw InputError(flag, "'" + dir + "': cannot create the directory: " + ec.message());
}

bool is_atomic_temp_name(const std::string& filename) {
  return filename.size() > 12 && filename.front() == '.' && filename.find(".tmp-") != std::string::npos;
}

void write_file_atomic(const std::string& path, std::string_view text) {
  AtomicFile f(path);
  f.write(text);
  f.commit();
}

void write_file_atomic_via(const std::string& path, const std::function<void(const std::string& temp)>& write,
                           bool keep_extension) {
  AtomicFile f(path, keep_extension);
  if (f.temp_path() != f.path()) f.close_fd();  // the writer opens it by name (and truncates it)
  write(f.temp_path());
  f.commit();
}

}  // namespace vtsim
