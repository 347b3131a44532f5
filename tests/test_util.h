#pragma once
// Helpers every kind of test uses: substring checks, reading a file whole, running a command line
// or the vtsim CLI with its output captured, and the checked-in test data directory.
// The test files are compiled in unity batches (tests/CMakeLists.txt): shared helpers live here
// once, not as file-local copies that would collide in a batch.
#include <doctest/doctest.h>
#include <sys/wait.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace vtsim::test {

// Iterations of a randomised property test: all of them in the Release build, a quarter under the
// sanitizers (tests/CMakeLists.txt defines VTSIM_TESTS_SANITIZED), where each costs 5-10x more
// and the memory checks need the code paths, not every random case, which Release already runs.
inline constexpr int property_runs(int n) {
#ifdef VTSIM_TESTS_SANITIZED
  return n / 4 > 0 ? n / 4 : 1;
#else
  return n;
#endif
}

inline bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

// The whole file (empty when it cannot be read).
inline std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Cuts the file at `path` to its first `fraction` of bytes (a transfer that stopped part way).
inline void cut_file(const std::string& path, double fraction) {
  const std::string bytes = slurp(path);
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      << bytes.substr(0, static_cast<std::size_t>(static_cast<double>(bytes.size()) * fraction));
}

// Runs `cmdline` through the shell with stdout and stderr into `log`; the exit code, or −1 when
// the command did not exit normally.
inline int run_shell(const std::string& cmdline, const std::string& log) {
  const std::string cmd = cmdline + " >" + log + " 2>&1";
  const int rc = std::system(cmd.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

// Runs `vtsim ARGS` (the CLI built beside the tests) like run_shell.
inline int run_vtsim(const std::string& args, const std::string& log) {
  return run_shell(std::string(VTSIM_CLI) + " " + args, log);
}

struct CliRun {
  int code = -1;  // exit code, −1 when vtsim did not exit normally
  std::string out, err;
};

// Runs the shell command `cmd`, whose stderr the command itself sends to err_path: stdout captured
// through a pipe, stderr read back from err_path (removed first, so it is a fresh file).
inline CliRun run_capture(const std::string& cmd, const std::string& err_path) {
  std::filesystem::remove(err_path);
  CliRun r;
  FILE* p = popen(cmd.c_str(), "r");
  REQUIRE(p != nullptr);
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.err = slurp(err_path);
  return r;
}

// Runs `vtsim ARGS` through the shell (test-controlled arguments without spaces), as run_capture.
inline CliRun run_vtsim_capture(const std::string& args, const std::string& err_path) {
  return run_capture(std::string(VTSIM_CLI) + " " + args + " 2>" + err_path, err_path);
}

inline const std::string kData = VTSIM_TEST_DATA;  // tests/data

// A little-endian, uncompressed, 8-bit grey TIFF of w × h pixels in tw × th tiles, texel (x, y) =
// (7x + 13y) mod 256 (padding of edge tiles included). claim_tw / claim_th, when non-zero, replace
// the tile size in the header only (the data stays tw × th tiles): a header lying about its tiles.
inline void write_tiled_tiff(const std::string& path, std::uint32_t w, std::uint32_t h, std::uint32_t tw, std::uint32_t th,
                             std::uint32_t claim_tw = 0, std::uint32_t claim_th = 0) {
  const std::uint32_t across = (w + tw - 1) / tw, down = (h + th - 1) / th, n = across * down;
  std::vector<std::uint8_t> f;
  auto u16 = [&](std::uint32_t v) { f.push_back(std::uint8_t(v)), f.push_back(std::uint8_t(v >> 8)); };
  auto u32 = [&](std::uint32_t v) { u16(v & 0xFFFF), u16(v >> 16); };
  // One tile: its offset and count sit in the entries, and its data right after the IFD.
  const std::uint32_t entries = 10, ifd = 8, arrays = ifd + 2 + entries * 12 + 4, data = n == 1 ? arrays : arrays + 8 * n;
  u16('I' | 'I' << 8), u16(42), u32(ifd);
  u16(entries);
  auto entry = [&](std::uint32_t tag, std::uint32_t type, std::uint32_t count, std::uint32_t value) {
    u16(tag), u16(type), u32(count);
    if (type == 3) u16(value), u16(0); else u32(value);
  };
  entry(256, 4, 1, w), entry(257, 4, 1, h), entry(258, 3, 1, 8), entry(259, 3, 1, 1), entry(262, 3, 1, 1);
  entry(277, 3, 1, 1), entry(322, 4, 1, claim_tw ? claim_tw : tw), entry(323, 4, 1, claim_th ? claim_th : th);
  entry(324, 4, n, n == 1 ? data : arrays), entry(325, 4, n, n == 1 ? tw * th : arrays + 4 * n);
  u32(0);
  for (std::uint32_t i = 0; i < n; ++i) u32(data + i * tw * th);
  for (std::uint32_t i = 0; i < n; ++i) u32(tw * th);
  f.resize(data);
  for (std::uint32_t t = 0; t < n; ++t)
    for (std::uint32_t j = 0; j < th; ++j)
      for (std::uint32_t i = 0; i < tw; ++i) f.push_back(std::uint8_t((t % across * tw + i) * 7 + (t / across * th + j) * 13));
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(f.data()), std::streamsize(f.size()));
}

}  // namespace vtsim::test
