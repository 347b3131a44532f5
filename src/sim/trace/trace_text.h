#pragma once
// Shared reading layer for untrusted text traces: the file and line limits, line splitting and
// number parsing, so that every format rejects the same bad input with the same words
// (docs/traces.md, "Errors and repairs"); and the writers' output file. Internal to
// src/sim/trace (trace_*.cpp and the format files in impl/).
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <glm/gtc/quaternion.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/text.h"
#include "sim/trace/trace_io.h"

namespace vtsim::trace_text {

// Reads a file line by line through a fixed buffer. Accepts "\n" and "\r\n" terminators, a
// missing final terminator, and skips a UTF-8 byte-order mark at the start. Rejects (InputError naming the file, and the line where there is one):
// a path that is not a regular file (a FIFO would block, a directory cannot be read), a file
// larger than limits.max_file_bytes, a line longer than limits.max_line_bytes, a NUL byte
// (binary data), and bytes that are not UTF-8. Not thread-safe; one reader per file.
class LineReader {
 public:
  LineReader(std::string path, const TraceReadLimits& limits);
  ~LineReader();
  LineReader(const LineReader&) = delete;
  LineReader& operator=(const LineReader&) = delete;

  // The next line without its terminator; false at the end of the file. The view stays valid
  // until the next call.
  bool next(std::string_view& line);
  std::int64_t line_no() const { return line_no_; }  // 1-based number of the last line returned
  std::string where() const { return at_line(path_, line_no_); }
  const std::string& path() const { return path_; }
  std::uint64_t bytes_read() const { return bytes_read_; }
  std::uint64_t file_bytes() const { return file_bytes_; }  // size when opened

  // A capacity guess for the poses of this file: one per `bytes_per_line`, at most 2^24.
  std::size_t expected_lines(std::size_t bytes_per_line) const {
    return static_cast<std::size_t>(std::min<std::uint64_t>(file_bytes_ / bytes_per_line, std::uint64_t{1} << 24));
  }

 private:
  void fill();

  std::string path_;
  TraceReadLimits limits_;
  int fd_ = -1;
  std::vector<char> buf_;
  std::size_t pos_ = 0, len_ = 0;
  bool eof_ = false;
  std::string line_;
  std::int64_t line_no_ = 0;
  std::uint64_t bytes_read_ = 0;
  std::uint64_t file_bytes_ = 0;
};

// A text file written in pieces; "-" is stdout. A file is written whole or not at all
// (core/atomic_file.h): a temporary beside it, renamed over it by close(); without close() (an
// exception on its way) the previous file stays. Throws InputError(path, "cannot create ...") when
// it cannot be created and InputError(path, or "stdout", "write failed: <reason>") when a write,
// the flush or the close fails. Not thread-safe.
class TextFileOut {
 public:
  explicit TextFileOut(const std::string& path);
  ~TextFileOut();  // drops a file close() did not commit (an exception is on its way)
  TextFileOut(const TextFileOut&) = delete;
  TextFileOut& operator=(const TextFileOut&) = delete;

  void write(std::string_view s);
  void close();  // flushes and closes, checking both

 private:
  std::unique_ptr<AtomicFile> file_;  // null for stdout
  std::string buffer_;                // written to file_ by 64 KiB
  bool stdout_ = false, closed_ = false;
  std::string where_;
};

using text::trim;  // spaces and tabs at both ends (core/text.h)
bool is_blank(std::string_view s);
bool is_comment(std::string_view s);        // first non-blank character is '#'

// Comma-separated fields, each trimmed. "a, b,,c" -> {"a", "b", "", "c"}.
void split_csv(std::string_view line, std::vector<std::string_view>& out);
// Fields separated by runs of spaces and tabs.
void split_ws(std::string_view line, std::vector<std::string_view>& out);

// A finite double (an optional leading '+' is accepted). Throws InputError(where, "field
// 'name': ...") for an empty field, trailing characters, NaN, infinity or out-of-range values.
double parse_double(std::string_view tok, const std::string& where, std::string_view field);

// A decimal time (digits, optional fraction, optional exponent) whose unit is 10^unit_pow10 ns
// (9: seconds, 0: nanoseconds), converted exactly to integer nanoseconds, rounded half up to the
// nearest one (at most 19 significant digits are used). Exact where a double is not: a 2011 Unix time with 4 decimals keeps its last digit.
// Throws InputError for non-numbers, NaN/inf and values beyond +-9.2e18 ns.
std::int64_t parse_time_ns(std::string_view tok, int unit_pow10, const std::string& where,
                           std::string_view field);

// An int in [lo, hi].
int parse_int(std::string_view tok, int lo, int hi, const std::string& where,
              std::string_view field);

// The quaternion policy shared by every reader (docs/traces.md): | |q| - 1 | <= kQuatUnitTolerance
// is kept bit-exact; <= kQuatNormSilent is normalised; <= kQuatNormTolerance is normalised and
// counted in repairs (an error if strict); a zero or farther-off quaternion is an InputError.
// text_tolerance raises the silent bound to what the printed digits explain (see print_tolerance).
void check_quat(glm::dquat& q, const std::string& where, bool strict, TraceRepairs& repairs,
                double text_tolerance = 0.0);

// Half a unit in the last printed digit of a decimal token: "0.6132" -> 5e-5, "1.5e-3" -> 5e-5;
// an integer token ("1", "0") is taken as exact: 0.
// A quaternion read from such text is off unit length by up to sum(|q_i| * half_ulp_i) from the
// rounding alone, which is not worth reporting as a repair.
double half_ulp_of_text(std::string_view tok);

// A token quoted for an error message: at most 40 bytes, non-printable bytes as \xNN.
std::string quote(std::string_view tok);

// Replaces what cannot go into a one-line UTF-8 text field (control characters, invalid UTF-8)
// with '?'.
std::string sanitize_line(std::string_view s);

}  // namespace vtsim::trace_text
