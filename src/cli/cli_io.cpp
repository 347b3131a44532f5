// The CLI's shared conventions: warnings, "-" for stdin/stdout, outputs checked up front (cli_io.h).
#include "cli/cli_io.h"

#include <fmt/core.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <system_error>

#include "core/atomic_file.h"


namespace vtsim::cli {

namespace {
std::size_t g_cli_io_warnings = 0;
}  // namespace

void warn(const std::string& message) {
  ++g_cli_io_warnings;
  std::fflush(stdout);  // in order with what the command printed before
  fmt::print(stderr, "vtsim: warning: {}\n", message);
}

std::size_t warnings_printed() { return g_cli_io_warnings; }

bool stderr_is_terminal() { return ::isatty(2) != 0; }

void progress_line(const std::string& text) {
  if (stderr_is_terminal()) fmt::print(stderr, "\r{:<70}", text);
  else fmt::print(stderr, "{}\n", text);
  std::fflush(stderr);
}

void progress_done() {
  if (stderr_is_terminal()) fmt::print(stderr, "\r{:70}\r", "");
}

void check_output(const std::string& flag, const std::string& path) {
  if (path.empty() || path == "-") return;
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw InputError(flag, "'" + path + "' is a directory; give a file name");
  const fs::path parent = fs::path(path).parent_path();
  const std::string dir = parent.empty() ? "." : parent.string();
  if (!fs::is_directory(dir, ec))
    throw InputError(flag, "'" + path + "': the directory '" + dir + "' does not exist (create it first)");
  if (::access(dir.c_str(), W_OK) != 0) throw InputError(flag, "'" + path + "': the directory '" + dir + "' is not writable");
  if (fs::exists(path, ec) && ::access(path.c_str(), W_OK) != 0)
    throw InputError(flag, "'" + path + "' exists and is not writable");
}

void check_input(const std::string& flag, const std::string& path) {
  if (path.empty() || path == "-") return;
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError(flag, "'" + path + "' is a directory, not a file");
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(flag, "'" + path + "': cannot open for reading (no such file, or no permission)");
}

void write_output(const std::string& path, const std::string& text) {
  if (path == "-") {
    std::fwrite(text.data(), 1, text.size(), stdout);
    return;  // a failed write to stdout is reported by main() at exit
  }
  write_file_atomic(path, text);
}

namespace {

// A new empty temporary file; its path.
std::string cli_io_temp_file(const char* what) {
  std::error_code ec;
  std::string dir = std::filesystem::temp_directory_path(ec).string();
  if (ec || dir.empty()) dir = "/tmp";
  std::string name = dir + "/vtsim-" + what + "-XXXXXX";
  const int fd = ::mkstemp(name.data());
  if (fd < 0) throw InputError(dir, std::string("cannot create a temporary file for ") + what);
  ::close(fd);
  return name;
}

}  // namespace

void write_output_via(const std::string& path, const std::function<void(const std::string&)>& write) {
  if (path != "-") {
    write_file_atomic_via(path, write);
    return;
  }
  const std::string temp = cli_io_temp_file("stdout");
  try {
    write(temp);
    std::unique_ptr<FILE, int (*)(FILE*)> in(std::fopen(temp.c_str(), "rb"), &std::fclose);
    if (!in) throw InputError(temp, "cannot read back");
    char buf[1 << 16];
    for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, in.get())) > 0;) std::fwrite(buf, 1, n, stdout);
    std::remove(temp.c_str());
  } catch (...) {
    std::remove(temp.c_str());
    throw;
  }
}

InputFile::InputFile(const std::string& path) : path_(path) {
  if (path != "-") return;
  temp_ = path_ = cli_io_temp_file("stdin");
  std::ofstream out(temp_, std::ios::binary | std::ios::trunc);
  char buf[1 << 16];  // an empty stdin leaves the file empty: the reader says so
  for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, stdin)) > 0;) out.write(buf, static_cast<std::streamsize>(n));
  if (std::ferror(stdin) || !out.flush()) {
    std::remove(temp_.c_str());
    throw InputError("-", "cannot copy stdin to a temporary file");
  }
}

InputFile::~InputFile() {
  if (!temp_.empty()) std::remove(temp_.c_str());
}

std::string InputFile::rename(const std::string& text) const {
  if (temp_.empty()) return text;
  std::string out;
  std::size_t from = 0;
  for (std::size_t p = text.find(temp_); p != std::string::npos; p = text.find(temp_, from)) {
    out.append(text, from, p - from);
    out += '-';
    from = p + temp_.size();
  }
  out.append(text, from, std::string::npos);
  return out;
}

}  // namespace vtsim::cli
