#include "sim/trace/trace_text.h"

#include <fcntl.h>
#include <fmt/core.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>

#include "core/input_file.h"
#include "core/utf8.h"

namespace vtsim::trace_text {

namespace {

constexpr std::size_t kReadChunk = 64 * 1024;

bool is_digit(char c) { return c >= '0' && c <= '9'; }


[[noreturn]] void bad_field(const std::string& where, std::string_view field, std::string_view tok,
                            std::string_view what) {
  throw InputError(where, fmt::format("field '{}': {} {}", field, quote(tok), what));
}

}  // namespace

LineReader::LineReader(std::string path, const TraceReadLimits& limits)
    : path_(std::move(path)), limits_(limits) {
  RegularFile f = open_regular_file(path_);
  if (f.size() > limits_.max_file_bytes)
    throw InputError(path_, fmt::format("file is {} bytes, more than the limit of {} bytes", f.size(), limits_.max_file_bytes));
  file_bytes_ = f.size();
  buf_.resize(kReadChunk);
  fd_ = f.release();  // nothing throws after this: the destructor closes it
}

LineReader::~LineReader() {
  if (fd_ >= 0) ::close(fd_);
}

void LineReader::fill() {
  pos_ = len_ = 0;
  ssize_t r;
  do {
    r = ::read(fd_, buf_.data(), buf_.size());
  } while (r < 0 && errno == EINTR);
  if (r < 0) throw InputError(path_, fmt::format("read error: {}", std::strerror(errno)));
  if (r == 0) {
    eof_ = true;
    return;
  }
  len_ = static_cast<std::size_t>(r);
  bytes_read_ += len_;
  if (bytes_read_ > limits_.max_file_bytes)  // the file grew while we read it
    throw InputError(path_, fmt::format("file is larger than the limit of {} bytes",
                                        limits_.max_file_bytes));
}

bool LineReader::next(std::string_view& line) {
  line_.clear();
  bool got_any = false;
  for (;;) {
    if (pos_ == len_) {
      if (eof_) break;
      fill();
      if (eof_) break;
    }
    const char* s = buf_.data() + pos_;
    const std::size_t avail = len_ - pos_;
    const auto* nl = static_cast<const char*>(std::memchr(s, '\n', avail));
    const std::size_t n = nl ? static_cast<std::size_t>(nl - s) : avail;
    got_any = true;
    // +1 leaves room for the '\r' of a CRLF terminator.
    if (line_.size() + n > limits_.max_line_bytes + 1)
      throw InputError(at_line(path_, line_no_ + 1),
                       fmt::format("line longer than {} bytes", limits_.max_line_bytes));
    line_.append(s, n);
    pos_ += n;
    if (nl) {
      ++pos_;
      break;
    }
  }
  if (!got_any) return false;
  ++line_no_;
  if (line_no_ == 1 && line_.compare(0, 3, "\xEF\xBB\xBF") == 0) line_.erase(0, 3);  // UTF-8 BOM
  if (!line_.empty() && line_.back() == '\r') line_.pop_back();
  if (line_.size() > limits_.max_line_bytes)
    throw InputError(where(), fmt::format("line longer than {} bytes", limits_.max_line_bytes));
  if (const void* z = std::memchr(line_.data(), '\0', line_.size()))
    throw InputError(where(),
                     fmt::format("NUL byte at column {} (binary data, not a text trace)",
                                 static_cast<const char*>(z) - line_.data() + 1));
  if (const std::size_t bad = find_invalid_utf8(line_); bad != std::string::npos)
    throw InputError(where(), fmt::format("invalid UTF-8 byte 0x{:02x} at column {}",
                                          static_cast<unsigned char>(line_[bad]), bad + 1));
  line = line_;
  return true;
}

TextFileOut::TextFileOut(const std::string& path)
    : stdout_(path == "-"), where_(stdout_ ? "stdout" : path) {
  if (!stdout_) file_ = std::make_unique<AtomicFile>(path);
}

TextFileOut::~TextFileOut() = default;

void TextFileOut::write(std::string_view s) {
  if (closed_) throw InputError(where_, "write after close");
  if (stdout_) {
    if (std::fwrite(s.data(), 1, s.size(), stdout) != s.size())
      throw InputError(where_, fmt::format("write failed: {}", std::strerror(errno)));
    return;
  }
  buffer_.append(s);
  if (buffer_.size() >= (std::size_t{1} << 16)) {
    file_->write(buffer_);
    buffer_.clear();
  }
}

void TextFileOut::close() {
  if (closed_) return;
  closed_ = true;
  if (stdout_) {
    if (std::fflush(stdout) != 0) throw InputError(where_, fmt::format("write failed: {}", std::strerror(errno)));
    return;
  }
  file_->write(buffer_);
  buffer_.clear();
  file_->commit();
}

bool is_blank(std::string_view s) { return trim(s).empty(); }

bool is_comment(std::string_view s) {
  s = trim(s);
  return !s.empty() && s.front() == '#';
}

void split_csv(std::string_view line, std::vector<std::string_view>& out) {
  out.clear();
  for (;;) {
    const std::size_t c = line.find(',');
    out.push_back(trim(line.substr(0, c)));
    if (c == std::string_view::npos) return;
    line.remove_prefix(c + 1);
  }
}

void split_ws(std::string_view line, std::vector<std::string_view>& out) {
  out.clear();
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const std::size_t b = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > b) out.push_back(line.substr(b, i - b));
  }
}

double parse_double(std::string_view tok, const std::string& where, std::string_view field) {
  std::string_view s = tok;
  if (s.empty()) bad_field(where, field, tok, "is empty");
  if (s.front() == '+') {
    s.remove_prefix(1);
    if (s.empty() || s.front() == '-' || s.front() == '+') bad_field(where, field, tok, "is not a number");
  }
  double v = 0.0;
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec == std::errc::result_out_of_range) bad_field(where, field, tok, "is out of range for a double");
  if (ec != std::errc() || p != s.data() + s.size()) bad_field(where, field, tok, "is not a number");
  if (!std::isfinite(v)) bad_field(where, field, tok, "is not finite");
  return v;
}

std::int64_t parse_time_ns(std::string_view tok, int unit_pow10, const std::string& where,
                           std::string_view field) {
  const std::string_view s = tok;
  std::size_t i = 0;
  const std::size_t n = s.size();
  bool neg = false;
  if (i < n && (s[i] == '+' || s[i] == '-')) neg = s[i++] == '-';
  constexpr std::uint64_t kMax = std::numeric_limits<std::uint64_t>::max();
  std::uint64_t m = 0;     // significant digits kept
  long long exp10 = 0;     // value = m * 10^exp10 (before the unit)
  int digits = 0;
  bool dropped = false, round_up = false;
  const auto add_digit = [&](unsigned d, bool fraction) {
    ++digits;
    if (!dropped && m <= (kMax - d) / 10) {
      m = m * 10 + d;
      if (fraction) --exp10;
    } else {
      if (!dropped) round_up = d >= 5;
      dropped = true;
      if (!fraction) ++exp10;
    }
  };
  while (i < n && is_digit(s[i])) add_digit(static_cast<unsigned>(s[i++] - '0'), false);
  if (i < n && s[i] == '.') {
    ++i;
    while (i < n && is_digit(s[i])) add_digit(static_cast<unsigned>(s[i++] - '0'), true);
  }
  if (digits == 0) bad_field(where, field, tok, s.empty() ? "is empty" : "is not a number");
  if (i < n && (s[i] == 'e' || s[i] == 'E')) {
    ++i;
    bool eneg = false;
    if (i < n && (s[i] == '+' || s[i] == '-')) eneg = s[i++] == '-';
    long long e = 0;
    int edigits = 0;
    while (i < n && is_digit(s[i])) {
      if (e < 100000) e = e * 10 + (s[i] - '0');
      ++i;
      ++edigits;
    }
    if (edigits == 0) bad_field(where, field, tok, "is not a number");
    exp10 += eneg ? -e : e;
  }
  if (i != n) bad_field(where, field, tok, "is not a number");
  if (round_up) {
    if (m == kMax) bad_field(where, field, tok, "is out of range");
    ++m;
  }
  const long long p = exp10 + unit_pow10;  // to nanoseconds
  std::uint64_t ns = 0;
  if (m != 0) {
    if (p >= 0) {
      if (p > 19) bad_field(where, field, tok, "is out of range (|t| > 9.2e9 s)");
      ns = m;
      for (long long k = 0; k < p; ++k) {
        if (ns > kMax / 10) bad_field(where, field, tok, "is out of range (|t| > 9.2e9 s)");
        ns *= 10;
      }
    } else if (-p <= 19) {
      std::uint64_t pw = 1;
      for (long long k = 0; k < -p; ++k) pw *= 10;
      ns = m / pw;
      const std::uint64_t r = m % pw;
      if (r >= pw - r) ++ns;  // round half up
    }  // else: below half a nanosecond, 0
  }
  if (ns > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max()))
    bad_field(where, field, tok, "is out of range (|t| > 9.2e9 s)");
  const auto v = static_cast<std::int64_t>(ns);
  return neg ? -v : v;
}

int parse_int(std::string_view tok, int lo, int hi, const std::string& where,
              std::string_view field) {
  std::string_view s = tok;
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  long long v = 0;
  if (!text::parse_whole(s, v))
    bad_field(where, field, tok, "is not an integer");
  if (v < lo || v > hi) bad_field(where, field, tok, fmt::format("is outside [{}, {}]", lo, hi));
  return static_cast<int>(v);
}

double half_ulp_of_text(std::string_view tok) {
  long long decimals = 0;
  std::size_t i = tok.find('.');
  const std::size_t e = tok.find_first_of("eE");
  if (i == std::string_view::npos && e == std::string_view::npos) return 0.0;  // "1", "0": exact
  if (i != std::string_view::npos && (e == std::string_view::npos || i < e))
    for (++i; i < tok.size() && is_digit(tok[i]); ++i) ++decimals;
  if (e != std::string_view::npos) {
    long long ev = 0;
    std::string_view es = tok.substr(e + 1);
    if (!es.empty() && es.front() == '+') es.remove_prefix(1);
    const auto [p, ec] = std::from_chars(es.data(), es.data() + es.size(), ev);
    if (ec != std::errc() || p != es.data() + es.size() || ev > 300 || ev < -300) return 0.0;
    decimals -= ev;
  }
  return 0.5 * std::pow(10.0, static_cast<double>(-std::clamp<long long>(decimals, -300, 300)));
}

void check_quat(glm::dquat& q, const std::string& where, bool strict, TraceRepairs& repairs,
                double text_tolerance) {
  const double n2 = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
  if (!(n2 > 0.0)) throw InputError(where, "zero quaternion");
  const double n = std::sqrt(n2);
  const double off = std::abs(n - 1.0);
  if (off <= kQuatUnitTolerance) return;
  if (off > kQuatNormTolerance)
    throw InputError(where, fmt::format("quaternion norm {:.9g} is not within {:g} of 1", n,
                                        kQuatNormTolerance));
  if (off > std::max(kQuatNormSilent, text_tolerance)) {
    if (strict)
      throw InputError(where, fmt::format("quaternion norm {:.9g} is not unit (strict mode)", n));
    ++repairs.quats_renormalised;
  }
  q = glm::dquat(q.w / n, q.x / n, q.y / n, q.z / n);
}

std::string quote(std::string_view tok) {
  constexpr std::size_t kMaxShown = 40;
  std::string out = "\"";
  for (std::size_t i = 0; i < tok.size() && i < kMaxShown; ++i) {
    const auto c = static_cast<unsigned char>(tok[i]);
    if (c >= 0x20 && c < 0x7F && c != '"' && c != '\\')
      out += static_cast<char>(c);
    else
      out += fmt::format("\\x{:02x}", c);
  }
  if (tok.size() > kMaxShown) out += "...";
  out += '"';
  return out;
}

std::string sanitize_line(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  std::size_t i = 0;
  while (i < s.size()) {
    const std::size_t n = utf8_sequence_length(s, i);
    const auto c = static_cast<unsigned char>(s[i]);
    if (n == 0 || (n == 1 && (c < 0x20 || c == 0x7F))) {
      out += '?';
      ++i;
    } else {
      out.append(s.substr(i, n));
      i += n;
    }
  }
  return out;
}

}  // namespace vtsim::trace_text
