#pragma once
// Helpers every kind of test uses: substring checks, reading a file whole, running a command line
// or the vtsim CLI with its output captured, and the checked-in test data directory.
// The test files are compiled in unity batches (tests/CMakeLists.txt): shared helpers live here
// once, not as file-local copies that would collide in a batch.
#include <doctest/doctest.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace vtsim::test {

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

// Runs `vtsim ARGS` through the shell (test-controlled arguments without spaces): stdout captured
// through a pipe, stderr through the file err_path (removed first, so it is a fresh file).
inline CliRun run_vtsim_capture(const std::string& args, const std::string& err_path) {
  std::filesystem::remove(err_path);
  const std::string cmd = std::string(VTSIM_CLI) + " " + args + " 2>" + err_path;
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

inline const std::string kData = VTSIM_TEST_DATA;  // tests/data

}  // namespace vtsim::test
