// Trace I/O speed: parsing against the cost of just reading the bytes and finding the lines
// (the floor any text parser pays), measured side by side in one run (bench/harness.h; medians of
// --reps repetitions, 9 by default, 5 quick); the file ../shared/traces-real/tum_fr2_desk_groundtruth.txt
// (or $VTSIM_BENCH_TUM) for the TUM import.
// Usage: build/bench/bench_trace [--quick] [--reps N] [--json FILE] [--filter S]
#include <fcntl.h>
#include <fmt/core.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "core/error.h"
#include "harness.h"
#include "sim/trace/trace_gen.h"
#include "sim/trace/trace_import.h"
#include "sim/trace/trace_io.h"
#include "sim/trace/trace_resample.h"
#include "sim/trace/trace_stats.h"

namespace {

// The reference: read the file in 64 KiB chunks and count its lines.
std::size_t read_and_count_lines(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) throw vtsim::InputError(path, "cannot open");
  std::vector<char> buf(64 * 1024);
  std::size_t lines = 0;
  ssize_t n;
  while ((n = ::read(fd, buf.data(), buf.size())) > 0)
    for (const char* p = buf.data(); (p = static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(buf.data() + n - p)))); ++p)
      ++lines;
  ::close(fd);
  return lines;
}

volatile std::size_t g_sink;

}  // namespace

int main(int argc, char** argv) {
  using namespace vtsim;
  bench::Harness h("trace", argc, argv, 9, 5);
  // The shared directory sits next to the source tree (as VTSIM_SHARED_DIR for the tests).
  const char* env_tum = std::getenv("VTSIM_BENCH_TUM");
  const std::string tum = env_tum && *env_tum ? env_tum
                                              : (std::filesystem::path(__FILE__).parent_path() /
                                                 "../../shared/traces-real/tum_fr2_desk_groundtruth.txt")
                                                    .string();
  const std::string tmp = (std::filesystem::temp_directory_path() / "vtsim_bench_trace.csv").string();

  TraceGenParams p = default_gen_params("turn");
  p.duration_s = h.pick(600.0, 60.0);
  const Trace t = generate_trace(p);
  save_trace(t, tmp);
  const auto native_bytes = static_cast<double>(std::filesystem::file_size(tmp));
  const auto poses = static_cast<double>(t.poses.size());
  h.param("turn_trace_seconds", p.duration_s);
  h.param("native_bytes", native_bytes);
  h.param("poses", poses);

  // Reference: read the same bytes in 64 KiB chunks and count the lines.
  const bench::Side read_native{"read_and_count_lines", {}, [&] { g_sink = read_and_count_lines(tmp); }};
  h.compare({.name = "load_trace_native", .metric = bench::Metric::kMBPerS, .work = native_bytes,
             .params = {{"poses", poses}}, .target_ratio = 0},
            {"load_trace", {}, [&] { g_sink = load_trace(tmp).poses.size(); }}, read_native);
  h.run({.name = "generate_turn", .metric = bench::Metric::kOpsPerS, .work = poses, .params = {{"unit", "poses/s"}}, .target_ratio = 0},
        {"generate_trace", {}, [&] { g_sink = generate_trace(p).poses.size(); }});
  h.run({.name = "save_trace_native", .metric = bench::Metric::kMBPerS, .work = native_bytes, .params = {}, .target_ratio = 0},
        {"save_trace", {}, [&] { save_trace(t, tmp); }});
  h.run({.name = "trace_stats", .metric = bench::Metric::kOpsPerS, .work = poses, .params = {{"unit", "poses/s"}}, .target_ratio = 0},
        {"trace_stats", {}, [&] { g_sink = static_cast<std::size_t>(trace_stats(t).frames); }});
  h.run({.name = "resample_60_to_100", .metric = bench::Metric::kOpsPerS, .work = poses, .params = {{"unit", "input poses/s"}}, .target_ratio = 0},
        {"resample", {}, [&] { g_sink = resample(t, 100.0).poses.size(); }});
  if (std::filesystem::exists(tum)) {
    const auto tum_bytes = static_cast<double>(std::filesystem::file_size(tum));
    h.compare({.name = "import_tum", .metric = bench::Metric::kMBPerS, .work = tum_bytes, .params = {{"file", tum}}, .target_ratio = 0},
              {"import_trace", {}, [&] { g_sink = import_trace(tum).poses.size(); }},
              {"read_and_count_lines", {}, [&] { g_sink = read_and_count_lines(tum); }});
  } else {
    fmt::print(stderr, "bench_trace: {} not found: import_tum skipped\n", tum);
  }
  std::filesystem::remove(tmp);
  return h.finish();
}
