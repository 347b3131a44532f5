#pragma once
// Fuzz targets: every parser of untrusted input (brief §7), one function per input kind taking
// raw bytes. The contract each target checks is the CLI's: the input is accepted, or rejected with
// an InputError (exit 2, a message naming the file, line or field). Anything else — another
// exception (the CLI's "internal error", exit 3), a crash, a sanitizer report, a hang — is a
// finding, and the target aborts so that libFuzzer keeps the input.
//
// Two drivers run the same targets (docs/robustness.md):
//  - fuzz_<name> (scripts/fuzz.sh, clang + libFuzzer + ASan/UBSan): explores;
//  - vtsim_fuzz_corpus (ctest fuzz_corpus, every build incl. ASan/UBSan): replays the checked-in
//    corpus tests/fuzz/corpus/<name>/ — the seeds and every finding so far — deterministically.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace vtsim::fuzz {

struct Target {
  const char* name;  // also the corpus directory
  void (*run)(const std::uint8_t* data, std::size_t size);
};

// Every target (fuzz_targets.cpp). Adding one: its file, its declaration below, a line in
// fuzz_targets.cpp and in CMakeLists.txt, and tests/fuzz/corpus/<name>/ with a seed.
const std::vector<Target>& targets();
const Target* find_target(std::string_view name);

// Runs fn; an InputError is the accepted way to refuse input. Any other exception aborts with
// the target's name and the message.
void expect_accept_or_reject(const char* target, const std::function<void()>& fn);

// Runs fn, a step that must succeed on an input already accepted (a round trip, a replay of a
// validated config): any exception, an InputError too, aborts with `what` and the message.
void must_succeed(const char* target, const char* what, const std::function<void()>& fn);

// The InputError messages of the refusals since the last call (oldest first), so that the corpus
// runner can show which seeds are accepted (a refused seed explores nothing past the refusal).
std::vector<std::string> take_refusals();

// The bytes written to a file of this process's scratch directory (removed at exit), named
// "input.<ext>" (some readers look at the extension). The same path every call for a given ext:
// a target reads its input before the next one is written.
std::string input_file(const std::uint8_t* data, std::size_t size, const std::string& ext);

// Splits the input at the first byte 0xFF (absent: everything is `first`): targets that need two
// inputs (a trace and the options to read it, two summaries to compare).
std::pair<std::string_view, std::string_view> split2(const std::uint8_t* data, std::size_t size);

// The targets (one file each).
void trace_native(const std::uint8_t* data, std::size_t size);
void trace_import(const std::uint8_t* data, std::size_t size);
void config(const std::uint8_t* data, std::size_t size);
void compare(const std::uint8_t* data, std::size_t size);
void store(const std::uint8_t* data, std::size_t size);
void obj(const std::uint8_t* data, std::size_t size);
void store_replay(const std::uint8_t* data, std::size_t size);
void image(const std::uint8_t* data, std::size_t size);
void sweep_spec(const std::uint8_t* data, std::size_t size);
void access_file(const std::uint8_t* data, std::size_t size);
void mesh_import(const std::uint8_t* data, std::size_t size);
void q3_entities(const std::uint8_t* data, std::size_t size);
void feedback(const std::uint8_t* data, std::size_t size);
void cachesim_formats(const std::uint8_t* data, std::size_t size);  // oracleGeneral and CSV traces (cachesim)

}  // namespace vtsim::fuzz
