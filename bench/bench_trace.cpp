// Trace I/O speed: parsing against the cost of just reading the bytes and finding the lines
// (the floor any text parser pays), measured side by side in one run; medians of 9 repetitions.
// Usage: build/bench/bench_trace [TUM_FILE]   (default: ../shared/traces-real/tum_fr2_desk_groundtruth.txt)
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
#include "sim/trace_gen.h"
#include "sim/trace_import.h"
#include "sim/trace_io.h"
#include "sim/trace_resample.h"
#include "sim/trace_stats.h"

namespace {

constexpr int kReps = 9;

double median_ms(const std::function<void()>& fn) {
  std::vector<double> ms;
  for (int i = 0; i < kReps; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    fn();
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(ms.begin(), ms.end());
  return ms[kReps / 2];
}

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

void row(const char* what, double ms, double ref_ms, std::uintmax_t bytes, std::size_t items) {
  const std::string ref = ref_ms > 0 ? fmt::format("{:.3f}", ref_ms) : "-";
  const std::string ratio = ref_ms > 0 ? fmt::format("{:.1f}x", ms / ref_ms) : "-";
  const std::string mbs = bytes ? fmt::format("{:.1f}", static_cast<double>(bytes) / 1e6 / (ms / 1e3)) : "-";
  fmt::print("{:<40} {:>9.3f} {:>9} {:>8} {:>9} {:>9.2f}\n", what, ms, ref, ratio, mbs,
             static_cast<double>(items) / 1e6 / (ms / 1e3));
}

}  // namespace

int main(int argc, char** argv) {
  using namespace vtsim;
  // The shared directory sits next to the source tree (as VTSIM_SHARED_DIR for the tests).
  const std::string tum = argc > 1 ? argv[1]
                                   : (std::filesystem::path(__FILE__).parent_path() /
                                      "../../shared/traces-real/tum_fr2_desk_groundtruth.txt")
                                         .string();
  const std::string tmp = (std::filesystem::temp_directory_path() / "vtsim_bench_trace.csv").string();

  TraceGenParams p = default_gen_params(TraceKind::turn);
  p.duration_s = 600.0;
  Trace t;
  const double gen_ms = median_ms([&] { t = generate_trace(p); });
  save_trace(t, tmp);
  const auto native_bytes = std::filesystem::file_size(tmp);
  const double read_ms = median_ms([&] { g_sink = read_and_count_lines(tmp); });
  const double load_ms = median_ms([&] { g_sink = load_trace(tmp).poses.size(); });
  const double save_ms = median_ms([&] { save_trace(t, tmp); });
  const double stats_ms = median_ms([&] { g_sink = static_cast<std::size_t>(trace_stats(t).frames); });
  const double resample_ms = median_ms([&] { g_sink = resample(t, 100.0).poses.size(); });

  fmt::print("{:<40} {:>9} {:>9} {:>8} {:>9} {:>9}\n", "operation (median of 9)", "ms", "ref ms", "ratio",
             "MB/s", "Mposes/s");
  row("generate turn, 600 s at 60 Hz", gen_ms, 0, 0, t.poses.size());
  row("load_trace native (ref: read+lines)", load_ms, read_ms, native_bytes, t.poses.size());
  row("save_trace native", save_ms, 0, native_bytes, t.poses.size());
  row("trace_stats", stats_ms, 0, 0, t.poses.size());
  row("resample 60 -> 100 Hz", resample_ms, 0, 0, t.poses.size());
  if (std::filesystem::exists(tum)) {
    const auto tum_bytes = std::filesystem::file_size(tum);
    std::size_t n = 0;
    const double tum_read_ms = median_ms([&] { g_sink = read_and_count_lines(tum); });
    const double tum_ms = median_ms([&] { n = import_trace(tum).poses.size(); });
    row("import TUM fr2_desk (ref: read+lines)", tum_ms, tum_read_ms, tum_bytes, n);
  }
  std::filesystem::remove(tmp);
  return 0;
}
