#pragma once
// What the format files in impl/ share (internal to src/sim/trace): the readers' checks and error
// words, the reader of the two timestamped text formats (TUM, EuRoC), and the writers' chunked
// output and times.
#include <fmt/format.h>

#include <glm/vec3.hpp>

#include <cstdint>
#include <iterator>
#include <string>
#include <string_view>
#include <utility>

#include "sim/trace/trace_format.h"
#include "sim/trace/trace_text.h"

namespace vtsim::format_impl {

// InputError(where, "coordinate x = ... m is not within +-1e10 m") beyond kMaxAbsCoordinate_m.
void check_position(const glm::dvec3& p, const std::string& where);

// InputError(where, "expected [at least ]N fields (layout), found M").
[[noreturn]] void wrong_field_count(const std::string& where, std::size_t want, std::size_t got,
                                    std::string_view layout, bool at_least = false);

// After the last line: records the line count in s; InputError at the last line (or line 1)
// when no pose was read.
void finish(const trace_text::LineReader& in, SourceTrace& s);

// A text format with a time, a position and a quaternion on each line.
struct TimedLayout {
  std::string_view name;         // the format's registry name (the trace is named "<name> <path>")
  std::string_view layout;       // for the field-count error
  std::string_view names[8];     // per field, for parse errors
  bool csv = false;              // comma-separated (EuRoC) or whitespace-separated (TUM; a line with
                                 // commas is split at them: --format tum reads TUM with commas)
  bool extra_columns = false;    // more than 8 fields allowed (ignored)
  int time_unit_pow10 = 0;       // the time unit is 10^k ns (9: seconds, 0: nanoseconds)
  bool w_first = false;          // quaternion w x y z (EuRoC) or x y z w (TUM)
  bool integer_time = false;     // a time with a fraction or exponent is an error (EuRoC: such
                                 // times are seconds and would round to a few nanoseconds)
};

// A decimal whose value is a whole number: "1403715524907143168", "-3", "1.5e9", "2.0"; not
// "1403715524.907143" or "15e-1". (Not a full number check: the parser does that.)
bool is_integer_text(std::string_view tok);

// Reads a timed text file: '#' comments and blank lines anywhere; times to integer nanoseconds,
// rebased to the first pose (t0_s set); a repeated time dropped (counted), one going backwards an
// error; quaternions per trace_text::check_quat with the rounding of their printed digits.
SourceTrace read_timed(const std::string& path, const TraceReadOptions& ro, const TimedLayout& form);

// Text handed to a sink in chunks of about 64 KiB: a long trace is written without building its
// whole text in memory. Call flush() at the end.
class ChunkedText {
 public:
  explicit ChunkedText(const TraceTextSink& sink) : sink_(sink) {}
  auto out() { return std::back_inserter(buf_); }
  void line_done() {
    if (buf_.size() >= 64 * 1024) flush();
  }
  void flush() {
    sink_(std::string_view(buf_.data(), buf_.size()));
    buf_.clear();
  }

 private:
  const TraceTextSink& sink_;
  fmt::memory_buffer buf_;
};

// Pose times as the readers will read them back: the shortest decimal of t_s (fmt's "{}", the
// native writer's digits, so an imported Unix time keeps its own) rounded half up to whole
// nanoseconds, as trace_text::parse_time_ns does.
class NanosecondTimes {
 public:
  NanosecondTimes(std::string where, std::string_view format) : where_(std::move(where)), format_(format) {}
  // The time of the next pose (index i), its decimal text in seconds (valid until the next call)
  // and its nanoseconds. Throws InputError(where + " pose i", ...) when they equal the previous
  // pose's: the reader would drop the pose as a repeated time.
  std::int64_t next(double t_s, std::size_t i, std::string_view& text);

 private:
  std::string where_;
  std::string_view format_;
  char text_[40] = {};
  std::int64_t prev_ns_ = 0;
  double prev_s_ = 0.0;
};

}  // namespace vtsim::format_impl
