#pragma once
// Untrusted input paths: reading a FIFO blocks until someone writes to it, /dev/zero never ends
// and a directory reads as nothing; every reader checks its path first.
#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <string>

#include "core/error.h"

namespace vtsim {

// Why a file of this st_mode is refused as input (every reader words it the same).
inline const char* not_regular_reason(mode_t mode) {
  return S_ISDIR(mode) ? "is a directory, not a file" : "not a regular file (a FIFO, socket or device)";
}

// Throws InputError(path, ...) unless path names a regular file (after symlinks). stat(), not
// open(): opening a FIFO for reading would block before any check. (A reader that opens first
// with O_NONBLOCK and checks the descriptor, as the trace reader does, is immune to the path
// changing in between.)
inline void require_regular_file(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) throw InputError(path, not_regular_reason(st.st_mode));
}

}  // namespace vtsim
