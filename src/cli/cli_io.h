#pragma once
// The CLI's shared conventions (README.md "Conventions"): one warning channel that -q never
// silences and --werror turns into exit 1; "-" for stdin or stdout wherever a file is read or
// written; output paths checked before the work, not after it.
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "core/error.h"

namespace vtsim::cli {

// Prints "vtsim: warning: MESSAGE" on stderr, whatever -q says, and counts it. Not thread-safe
// (commands warn from their own thread).
void warn(const std::string& message);
// Warnings printed since the program started.
std::size_t warnings_printed();

// Progress on stderr (README.md "Conventions"): on a terminal one line rewritten in place with
// "\r"; in a log (stderr not a terminal) one line each, never a "\r". progress_done() clears a
// terminal's line and prints nothing in a log.
bool stderr_is_terminal();
void progress_line(const std::string& text);
void progress_done();

// Throws InputError naming `flag` when `path` cannot be written: its directory is missing or not
// writable, or it is a directory. "-" (stdout) and "" (not given) pass. Creates nothing.
void check_output(const std::string& flag, const std::string& path);
// Throws InputError naming `flag` when `path` cannot be opened for reading. "-" (stdin) passes.
void check_input(const std::string& flag, const std::string& path);

// Writes `text` to `path`, or to stdout when `path` is "-". Throws InputError naming the path. A
// file is written whole or not at all (core/atomic_file.h): a failed run leaves it as it was.
void write_output(const std::string& path, const std::string& text);
// For writers that take a path (write(path) creates the file): a file is written to a temporary
// beside it, renamed into place once write() returns; "-" writes to a temporary file, then copies
// it to stdout and removes it.
void write_output_via(const std::string& path, const std::function<void(const std::string&)>& write);

// stdin as a file for readers that take a path: for "-" reads all of stdin into a temporary file
// (removed on destruction); any other path passes through. Not copyable.
class InputFile {
 public:
  explicit InputFile(const std::string& path);
  ~InputFile();
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;
  const std::string& path() const { return path_; }
  // An InputError's text with the temporary file's name replaced by "-" (stdin).
  std::string rename(const std::string& text) const;

 private:
  std::string path_, temp_;
};

// f(path) with `path` readable as a file, "-" meaning stdin: errors name "-", not a temporary
// file. For every reader that takes a path (traces, access files, configs).
template <class F>
auto with_input(const std::string& path, F&& f) {
  InputFile in(path);
  try {
    return f(in.path());
  } catch (const InputError& e) {
    if (path != "-") throw;
    throw InputError(in.rename(e.where()), std::string(e.what()).substr(e.where().empty() ? 0 : e.where().size() + 2));
  }
}

// with_input over several paths, of which at most one is "-" (stdin): f(paths) with "-" readable
// as a file. Throws InputError(`option`, ...) when "-" appears twice or `stdin_taken` (another
// option already reads stdin) and one is "-".
template <class F>
auto with_inputs(const std::vector<std::string>& paths, const std::string& option, bool stdin_taken, F&& f) {
  std::size_t dash = paths.size();
  for (std::size_t i = 0; i < paths.size(); ++i)
    if (paths[i] == "-") {
      if (dash != paths.size()) throw InputError(option, "- (stdin) given twice");
      if (stdin_taken) throw InputError(option, "- and another option cannot both read stdin");
      dash = i;
    }
  if (dash == paths.size()) return f(paths);
  return with_input("-", [&](const std::string& p) {
    std::vector<std::string> with = paths;
    with[dash] = p;
    return f(with);
  });
}

}  // namespace vtsim::cli
