#pragma once
// Access sequences as text files (docs/cache.md, "Miss-ratio curves"): what `vtsim mrc` reads and
// what a replay's recorder writes. The format, line by line:
//   key [size]   one access: key decimal or 0x-hex (below 2^64 - 1, which is never a key), size
//                a decimal in [1, 2^40] (default 1: a page)
//   frame        the next access starts a new frame (AccessLog::frame_start)
//   # ...        a comment, also after an access; blank lines are skipped
// Whitespace is spaces or tabs; lines end in \n or \r\n. Every error names path:line.
// Thread-safety: the functions share no state.
#include <cstdint>
#include <string>
#include <string_view>

#include "cache/policy/access.h"

namespace vtsim {

// At most 2 GiB of text (about 80 million accesses at 26 bytes a line).
inline constexpr std::uint64_t kMaxAccessFileBytes = std::uint64_t{2} << 30;

// Parses the text of an access file; `name` is the path used in messages. Throws InputError.
AccessLog parse_accesses(std::string_view text, const std::string& name);
// Reads a regular file (core/input_file.h) of at most kMaxAccessFileBytes. Throws InputError, also
// when it holds no access (an empty input is an error, README.md "Conventions").
AccessLog read_access_file(const std::string& path);

// The text parse_accesses reads back to the same log: a comment header, keys in 0x-hex with
// their sizes, a `frame` line before each frame's first access. Throws std::invalid_argument for
// frame_start not non-decreasing or beyond the accesses, and for an
// access the reader would refuse (key ~0, size outside [1, 2^40]).
std::string format_accesses(const AccessLog& log);
// Writes format_accesses(log) to path. Throws InputError(path, ...) when it cannot.
void write_access_file(const std::string& path, const AccessLog& log);

}  // namespace vtsim
