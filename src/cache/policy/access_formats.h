#pragma once
// libCacheSim's trace formats as access sequences (docs/cache.md, "Cache simulation on access
// files"), so that `vtsim cachesim` reads the files libCacheSim users already have:
//
//   oracleGeneral  libCacheSim's binary (traceReader/customizedReader/oracle/oracleGeneralBin.h):
//                  packed 24-byte little-endian records
//                    uint32 clock_time, uint64 obj_id, uint32 obj_size, int64 next_access_vtime
//                  obj_id is the key, obj_size the size. As libCacheSim's reader does by default
//                  (ignore_size_zero_req), records of size 0 are skipped (counted). clock_time and
//                  next_access_vtime are read and not used: vtsim recomputes next uses from the
//                  sequence (cache/policy/belady.h), the same for a file libCacheSim wrote.
//   csv            text with one request per line, columns chosen as libCacheSim's csv reader
//                  options name them (obj-id-col, obj-size-col, time-col, has-header, delimiter,
//                  obj-id-is-num): a column is a 1-based number or, with a header, its name.
//                  Fields may be double-quoted ("" inside is a quote). Numeric ids are decimal or
//                  0x-hex below 2^64 - 1; with obj_id_is_num false the id is any text, hashed
//                  (FNV-1a 64) to a key. Sizes are decimal in [1, 2^40]; a time is a decimal
//                  (checked, not used).
//
// Untrusted input: every error names path:record (binary, 1-based) or path:line plus the field;
// a file that is not a whole number of records is refused (truncated); an empty input or one
// without a request is an error. Files up to kMaxAccessFileBytes.
// Thread-safety: the functions share no state.
#include <cstdint>
#include <string>
#include <string_view>

#include "cache/policy/access.h"

namespace vtsim {

inline constexpr std::size_t kOracleGeneralRecordBytes = 24;

struct OracleGeneralRead {
  AccessLog log;                    // no frames
  std::uint64_t zero_size_skipped = 0;
};

// The bytes of an oracleGeneral file; `name` is the path used in messages. Throws InputError.
OracleGeneralRead parse_oracle_general(std::string_view bytes, const std::string& name);
OracleGeneralRead read_oracle_general(const std::string& path);
// The records of `log` in oracleGeneral (clock_time = index, next_access_vtime from the
// sequence, -1 for none): what libCacheSim reads back. Throws std::invalid_argument for a size
// above 2^32 - 1 or key ~0.
std::string format_oracle_general(const AccessLog& log);

struct CsvAccessOptions {
  std::string obj_id_col;    // required: a 1-based column number, or a header name
  std::string obj_size_col;  // empty: no size (every request weighs 1)
  std::string time_col;      // empty: none
  bool has_header = false;   // the first line names the columns (and is not a request)
  char delimiter = ',';
  bool obj_id_is_num = true;  // false: ids are text, hashed to keys
};

// Throws InputError: `name`:line for the data, `name` for a column the header or the first line
// does not have (the column named as given).
AccessLog parse_access_csv(std::string_view text, const std::string& name, const CsvAccessOptions& o);
AccessLog read_access_csv(const std::string& path, const CsvAccessOptions& o);

}  // namespace vtsim
