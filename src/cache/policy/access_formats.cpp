#include "cache/policy/access_formats.h"

#include <fmt/format.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "cache/policy/access_io.h"
#include "cache/policy/belady.h"
#include "cache/policy/i_replacement.h"
#include "core/error.h"
#include "core/hash.h"
#include "core/input_file.h"
#include "core/text.h"

namespace vtsim {

namespace {

constexpr std::uint64_t kFormatsMaxSize = std::uint64_t{1} << 40;  // as access files (mrc sums sizes)

template <class T>
T formats_load_le(const unsigned char* p) {
  T v = 0;
  for (std::size_t i = 0; i < sizeof(T); ++i) v |= static_cast<T>(static_cast<T>(p[i]) << (8 * i));
  return v;
}

template <class T>
void formats_store_le(std::string& out, T v) {
  for (std::size_t i = 0; i < sizeof(T); ++i) out.push_back(static_cast<char>((static_cast<std::uint64_t>(v) >> (8 * i)) & 0xff));
}

std::string formats_shown(std::string_view t) {
  std::string s = t.size() > 40 ? std::string(t.substr(0, 40)) + "..." : std::string(t);
  for (char& c : s)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) == 0x7f) c = '?';
  return s;
}

// One line's fields split on `delim`; a field may be double-quoted ("" a quote inside). Throws
// InputError(where, ...) for an unterminated quote or text after a closing quote.
void csv_split(std::string_view line, char delim, const std::string& where, std::vector<std::string>& out) {
  out.clear();
  std::size_t i = 0;
  while (true) {
    std::string field;
    if (i < line.size() && line[i] == '"') {
      ++i;
      bool closed = false;
      while (i < line.size()) {
        if (line[i] == '"') {
          if (i + 1 < line.size() && line[i + 1] == '"') {
            field.push_back('"');
            i += 2;
            continue;
          }
          ++i;
          closed = true;
          break;
        }
        field.push_back(line[i++]);
      }
      if (!closed) throw InputError(where, fmt::format("field {}: a quote opened and never closed", out.size() + 1));
      if (i < line.size() && line[i] != delim)
        throw InputError(where, fmt::format("field {}: text after the closing quote", out.size() + 1));
    } else {
      const std::size_t e = line.find(delim, i);
      field.assign(line.substr(i, e == std::string_view::npos ? std::string_view::npos : e - i));
      i = e == std::string_view::npos ? line.size() : e;
    }
    out.push_back(std::string(text::trim(field)));
    if (i >= line.size()) break;
    ++i;  // the delimiter
    if (i == line.size()) {  // a trailing delimiter: one empty field more
      out.emplace_back();
      break;
    }
  }
}

// The next line of text (consumed), without its \n or \r\n.
std::string_view csv_next_line(std::string_view& text) {
  const std::size_t nl = text.find('\n');
  std::string_view line = text.substr(0, nl);
  text.remove_prefix(nl == std::string_view::npos ? text.size() : nl + 1);
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  return line;
}

// A column option resolved to a 0-based index: a 1-based number, or a header name.
std::size_t csv_column(const std::string& spec, const char* option, const std::vector<std::string>* header,
                       const std::string& name) {
  std::uint64_t n = 0;
  if (text::parse_whole(std::string_view(spec), n)) {
    if (n < 1 || n > 100000)
      throw InputError(name, fmt::format("{} {}: a column number is 1-based, at most 100000", option, n));
    return static_cast<std::size_t>(n - 1);
  }
  if (header == nullptr)
    throw InputError(name, fmt::format("{} '{}': a column name needs a header (has-header), or give the column's number",
                                       option, formats_shown(spec)));
  for (std::size_t i = 0; i < header->size(); ++i)
    if ((*header)[i] == spec) return i;
  std::string cols;
  for (std::size_t i = 0; i < header->size() && i < 20; ++i) cols += (i ? ", " : "") + formats_shown((*header)[i]);
  throw InputError(name, fmt::format("{} '{}' is not a column of the header (columns: {})", option, formats_shown(spec), cols));
}

bool csv_key(std::string_view t, std::uint64_t& v) {
  int base = 10;
  if (t.size() > 2 && t[0] == '0' && (t[1] == 'x' || t[1] == 'X')) {
    t.remove_prefix(2);
    base = 16;
  }
  return text::parse_whole(t, v, base);
}

}  // namespace

OracleGeneralRead parse_oracle_general(std::string_view bytes, const std::string& name) {
  if (bytes.empty()) throw InputError(name, "is empty: an oracleGeneral trace holds 24-byte records");
  if (bytes.size() % kOracleGeneralRecordBytes != 0)
    throw InputError(at_line(name, static_cast<long long>(bytes.size() / kOracleGeneralRecordBytes + 1)),
                     fmt::format("truncated: the file's {} bytes end {} bytes into this record (records are {} bytes: "
                                 "uint32 clock_time, uint64 obj_id, uint32 obj_size, int64 next_access_vtime)",
                                 bytes.size(), bytes.size() % kOracleGeneralRecordBytes, kOracleGeneralRecordBytes));
  OracleGeneralRead r;
  const std::size_t n = bytes.size() / kOracleGeneralRecordBytes;
  r.log.accesses.reserve(n);
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  for (std::size_t i = 0; i < n; ++i, p += kOracleGeneralRecordBytes) {
    const std::uint64_t id = formats_load_le<std::uint64_t>(p + 4);
    const std::uint32_t size = formats_load_le<std::uint32_t>(p + 12);
    if (id == kNoKey)
      throw InputError(at_line(name, static_cast<long long>(i + 1)), "obj_id 0xffffffffffffffff is reserved (never a key)");
    if (size == 0) {  // libCacheSim's reader skips them (ignore_size_zero_req, its default)
      ++r.zero_size_skipped;
      continue;
    }
    r.log.accesses.push_back(Access{id, size});
  }
  if (r.log.accesses.empty())
    throw InputError(name, fmt::format("holds no request: all {} records have obj_size 0", n));
  return r;
}

OracleGeneralRead read_oracle_general(const std::string& path) {
  const std::string bytes = read_regular_file(path, kMaxAccessFileBytes, "split the trace, or sample it");
  return parse_oracle_general(bytes, path);
}

std::string format_oracle_general(const AccessLog& log) {
  const std::vector<std::uint64_t> next = next_uses(log.accesses);
  std::string out;
  out.reserve(log.accesses.size() * kOracleGeneralRecordBytes);
  for (std::size_t i = 0; i < log.accesses.size(); ++i) {
    const Access& a = log.accesses[i];
    if (a.size > 0xffffffffu || a.size == 0)
      throw std::invalid_argument(fmt::format("format_oracle_general: access {}: size {} outside [1, 2^32 - 1]", i, a.size));
    formats_store_le<std::uint32_t>(out, static_cast<std::uint32_t>(i));
    formats_store_le<std::uint64_t>(out, a.key);
    formats_store_le<std::uint32_t>(out, static_cast<std::uint32_t>(a.size));
    formats_store_le<std::int64_t>(out, next[i] == log.accesses.size() ? std::int64_t{-1} : static_cast<std::int64_t>(next[i]));
  }
  return out;
}

AccessLog parse_access_csv(std::string_view text, const std::string& name, const CsvAccessOptions& o) {
  if (o.obj_id_col.empty()) throw InputError(name, "obj-id-col is required: the column of the object id");
  if (o.delimiter == '"' || o.delimiter == '\n' || o.delimiter == '\r')
    throw InputError(name, "delimiter cannot be a quote or a line end");
  if (text.empty()) throw InputError(name, "is empty: a CSV trace holds one request per line");
  std::vector<std::string> fields, header;
  long long line_no = 0;
  std::size_t id_col = 0, size_col = 0, time_col = 0;
  const bool has_size = !o.obj_size_col.empty(), has_time = !o.time_col.empty();
  bool resolved = false;
  const auto resolve = [&](const std::vector<std::string>* h) {
    id_col = csv_column(o.obj_id_col, "obj-id-col", h, name);
    if (has_size) size_col = csv_column(o.obj_size_col, "obj-size-col", h, name);
    if (has_time) time_col = csv_column(o.time_col, "time-col", h, name);
    resolved = true;
  };
  AccessLog log;
  while (!text.empty()) {
    const std::string_view line = csv_next_line(text);
    ++line_no;
    if (text::trim(line).empty()) continue;
    const std::string where = at_line(name, line_no);
    csv_split(line, o.delimiter, where, fields);
    if (!resolved) {
      if (o.has_header) {
        header = fields;
        resolve(&header);
        continue;
      }
      resolve(nullptr);
    }
    const auto field = [&](std::size_t col, const char* option) -> const std::string& {
      if (col >= fields.size())
        throw InputError(where, fmt::format("{} fields, but {} is column {}", fields.size(), option, col + 1));
      return fields[col];
    };
    Access a;
    const std::string& id = field(id_col, "obj-id-col");
    if (o.obj_id_is_num) {
      if (!csv_key(id, a.key))
        throw InputError(where, fmt::format("obj-id '{}' is not a decimal or 0x-hex integer below 2^64 (for text ids: "
                                            "obj-id-is-num false)", formats_shown(id)));
      if (a.key == kNoKey) throw InputError(where, "obj-id 0xffffffffffffffff is reserved (never a key)");
    } else {
      if (id.empty()) throw InputError(where, "obj-id is empty");
      a.key = fnv1a64(id);
      if (a.key == kNoKey) a.key = 0;  // one value of 2^64 folded: never a key
    }
    if (has_size) {
      const std::string& s = field(size_col, "obj-size-col");
      if (!text::parse_whole(std::string_view(s), a.size) || a.size < 1 || a.size > kFormatsMaxSize)
        throw InputError(where, fmt::format("obj-size '{}' is not a decimal integer in [1, 2^40]", formats_shown(s)));
    }
    if (has_time) {
      const std::string& t = field(time_col, "time-col");
      double v = 0;
      if (!text::parse_whole(std::string_view(t), v) || !std::isfinite(v))
        throw InputError(where, fmt::format("time '{}' is not a finite number", formats_shown(t)));
    }
    log.accesses.push_back(a);
  }
  if (log.accesses.empty())
    throw InputError(name, o.has_header && resolved ? "holds a header and no request" : "holds no request (only blank lines)");
  return log;
}

AccessLog read_access_csv(const std::string& path, const CsvAccessOptions& o) {
  const std::string text = read_regular_file(path, kMaxAccessFileBytes, "split the trace, or sample it");
  return parse_access_csv(text, path, o);
}

}  // namespace vtsim
