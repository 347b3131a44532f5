#pragma once
// Helpers for the trace tests: a scratch directory, file writing, and catching InputError text.
#include <doctest/doctest.h>
#include <stdlib.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

#include "core/error.h"
#include "core/trace.h"
#include "test_util.h"

namespace vtsim::test {

// The camera body frame FLU (docs/traces.md): +x forward, +y left, +z up.
inline const glm::dvec3 kForward(1, 0, 0), kLeft(0, 1, 0), kUp(0, 0, 1);

// A fresh directory under the system temp dir, removed with everything in it at scope exit.
class ScratchDir {
 public:
  ScratchDir() {
    std::string tmpl = (std::filesystem::temp_directory_path() / "vtsim_trace_XXXXXX").string();
    if (!mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
    path_ = tmpl;
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// Replaces the file by a new one (remove, then create): truncating it in place would make ext4
// flush it to disk on close (auto_da_alloc), which costs milliseconds per write.
inline void write_file(const std::string& path, const std::string& bytes) {
  std::error_code ec;
  std::filesystem::remove(path, ec);
  std::ofstream f(path, std::ios::binary);
  f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  REQUIRE(f.good());
}

// The message of the InputError fn throws; fails the test if it throws nothing or something else.
inline std::string input_error(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  } catch (const std::exception& e) {
    FAIL("expected InputError, got: " << e.what());
    return {};
  }
  FAIL("expected InputError, nothing was thrown");
  return {};
}

// Runs `vtsim ARGS` with stderr through a file in `dir` (run_vtsim_capture).
inline CliRun vtsim_run(const ScratchDir& dir, const std::string& args) {
  return run_vtsim_capture(args, dir.file("stderr.txt"));
}

inline bool same_bits(double a, double b) {
  return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

// Rotates v by the unit quaternion q.
// Componentwise |a - b| <= tol, with a's components in the failure message.
inline void check_vec(const glm::dvec3& a, const glm::dvec3& b, double tol = 1e-15) {
  CAPTURE(a.x);
  CAPTURE(a.y);
  CAPTURE(a.z);
  CHECK(std::abs(a.x - b.x) <= tol);
  CHECK(std::abs(a.y - b.y) <= tol);
  CHECK(std::abs(a.z - b.z) <= tol);
}

inline glm::dvec3 rotate(const glm::dquat& q, const glm::dvec3& v) { return q * v; }

// Appends `frames` poses equal to the last one at 60 Hz: the camera stops.
inline void hold_last_pose(Trace& t, int frames) {
  const Pose last = t.poses.back();
  for (int f = 1; f <= frames; ++f) {
    Pose p = last;
    p.t_s = last.t_s + f / 60.0;
    t.poses.push_back(p);
  }
}

}  // namespace vtsim::test
