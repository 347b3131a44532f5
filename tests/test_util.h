#pragma once
// Helpers every kind of test uses: substring checks, reading a file whole, running a command line
// or the vtsim CLI with its output captured in a log file, and the checked-in test data directory.
// The test files are compiled in unity batches (tests/CMakeLists.txt): shared helpers live here
// once, not as file-local copies that would collide in a batch.
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

namespace vtsim::test {

inline bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

// The whole file (empty when it cannot be read).
inline std::string slurp(const std::string& path) {
  std::ifstream in(path);
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

inline const std::string kData = VTSIM_TEST_DATA;  // tests/data

}  // namespace vtsim::test
