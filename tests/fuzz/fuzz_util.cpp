#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <utility>

#include "core/error.h"
#include "fuzz_targets.h"
#include "store_test_util.h"

namespace vtsim::fuzz {

namespace {

std::vector<std::string>& refusals() {
  static std::vector<std::string> r;
  return r;
}

}  // namespace

std::vector<std::string> take_refusals() { return std::exchange(refusals(), {}); }

void expect_accept_or_reject(const char* target, const std::function<void()>& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    // The documented refusal (the CLI's exit 2).
    if (refusals().size() < 16) refusals().emplace_back(e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vtsim fuzz %s: not an InputError: %s\n", target, e.what());
    std::abort();
  }
}

void must_succeed(const char* target, const char* what, const std::function<void()>& fn) {
  try {
    fn();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vtsim fuzz %s: %s failed on an accepted input: %s\n", target, what, e.what());
    std::abort();
  }
}

std::string input_file(const std::uint8_t* data, std::size_t size, const std::string& ext) {
  static const test::TempDir dir;  // removed at exit
  const std::filesystem::path p = dir.path / ("input." + ext);
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  f.close();
  if (!f) {
    std::fprintf(stderr, "vtsim fuzz: cannot write %s\n", p.c_str());
    std::abort();
  }
  return p.string();
}

std::pair<std::string_view, std::string_view> split2(const std::uint8_t* data, std::size_t size) {
  const std::string_view all(reinterpret_cast<const char*>(data), size);
  const std::size_t cut = all.find('\xff');
  if (cut == std::string_view::npos) return {all, {}};
  return {all.substr(0, cut), all.substr(cut + 1)};
}

}  // namespace vtsim::fuzz
