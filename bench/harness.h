#pragma once
// The benchmark harness every bench/bench_*.cpp uses (docs/bench.md): warm-up, N timed
// repetitions with per-repetition setup kept out of the timing, median and spread, a reference
// measured side by side in the same run (repetitions interleaved, order alternating) with the
// ratio printed, quick mode, and one JSON schema ("vtsim-bench/1") for every benchmark.
//
//   int main(int argc, char** argv) {
//     vtsim::bench::Harness h("lru", argc, argv);    // --quick --json PATH --reps N ...
//     h.compare({.name = "get", .work = n_ops},
//               {"ours", setup_a, [&] { ... }}, {"textbook", setup_b, [&] { ... }});
//     return h.finish();                             // prints the table, writes the JSON
//   }
//
// Single-threaded; not thread-safe. Timing: std::chrono::steady_clock around each repetition's
// run() only.
#include <sys/utsname.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <deque>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

namespace vtsim::bench {

// Keeps `value` (and everything it points to) observable, so the computation that produced it is
// not optimised away; the GCC/Clang idiom of Google Benchmark's DoNotOptimize.
template <class T>
inline void do_not_optimize(const T& value) {
  asm volatile("" : : "r,m"(value) : "memory");
}
template <class T>
inline void do_not_optimize(T& value) {
  if constexpr (std::is_trivially_copyable_v<T> && sizeof(T) <= sizeof(void*))
    asm volatile("" : "+m,r"(value) : : "memory");
  else
    asm volatile("" : "+m"(value) : : "memory");
}
// Forces pending writes to memory to be treated as observed (ClobberMemory).
inline void clobber_memory() { asm volatile("" : : : "memory"); }

// What one result measures; `work` is per repetition.
enum class Metric {
  kNsPerOp,   // "ns/op": elapsed ns / work (ops); lower is better
  kMsPerRep,  // "ms": elapsed ms per repetition (work ignored); lower is better
  kMBPerS,    // "MB/s": work (bytes) / elapsed s / 1e6; higher is better
  kOpsPerS,   // "op/s": work (ops) / elapsed s; higher is better
};
inline const char* metric_unit(Metric m) {
  switch (m) {
    case Metric::kNsPerOp: return "ns/op";
    case Metric::kMsPerRep: return "ms";
    case Metric::kMBPerS: return "MB/s";
    case Metric::kOpsPerS: return "op/s";
  }
  return "?";
}
inline bool higher_is_better(Metric m) { return m == Metric::kMBPerS || m == Metric::kOpsPerS; }

struct Case {
  std::string name;                   // unique within the benchmark, e.g. "get_zipf"
  Metric metric = Metric::kNsPerOp;
  double work = 1;                    // ops or bytes per repetition (see Metric)
  nlohmann::json params = nlohmann::json::object();  // sizes, seeds, hit ratios... (free form)
  double target_ratio = 0;            // the ratio this case aims for (0: none); see Result::ratio
  // Quick mode's inputs are smaller and its repetitions fewer, so a target set for the full run
  // is not held there (not printed, not checked, null in the JSON) unless the case says it holds.
  bool target_in_quick = false;
};

// One side of a measurement: setup() runs before every repetition (and warm-up), untimed;
// run() is timed. setup may be empty.
struct Side {
  std::string name;
  std::function<void()> setup;
  std::function<void()> run;
};

struct Summary {
  std::vector<double> samples;  // one value per repetition, in Metric units, in run order
  double median = 0, min = 0, max = 0;
  double p10 = 0, p90 = 0;      // percentiles, linear interpolation between order statistics
  double mad = 0;               // median absolute deviation from the median (unscaled)
};

struct Result {
  Case spec;
  std::string side;                      // name of the measured side ("ours")
  Summary ours;
  std::optional<std::string> reference;  // reference side's name, when compared
  Summary ref;
  // How many times better than the reference (> 1: ours wins): per repetition pair (the two
  // sides' i-th repetitions, measured back to back) ref/ours for lower-is-better metrics, ours/ref
  // for higher-is-better ones; `ratio` is the median of those pair ratios, which cancels load
  // that drifts between pairs on a shared machine. 0 without a reference.
  double ratio = 0;
  double ratio_of_medians = 0;  // the same from the two medians, for comparison
  std::vector<double> pair_ratios;
  bool meets_target = true;
};

// Percentile p in [0, 1] of sorted values (linear interpolation, "type 7").
inline double percentile_sorted(const std::vector<double>& v, double p) {
  if (v.empty()) return 0;
  const double pos = p * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (v[hi] - v[lo]) * (pos - static_cast<double>(lo));
}

inline Summary summarize(std::vector<double> samples) {
  Summary s;
  s.samples = samples;
  if (samples.empty()) return s;
  std::sort(samples.begin(), samples.end());
  s.min = samples.front();
  s.max = samples.back();
  s.median = percentile_sorted(samples, 0.5);
  s.p10 = percentile_sorted(samples, 0.1);
  s.p90 = percentile_sorted(samples, 0.9);
  std::vector<double> dev;
  for (double x : samples) dev.push_back(std::fabs(x - s.median));
  std::sort(dev.begin(), dev.end());
  s.mad = percentile_sorted(dev, 0.5);
  return s;
}

struct Options {
  bool quick = false;      // --quick or VTSIM_BENCH_QUICK=1: fewer repetitions, smaller inputs
  std::string json_path;   // --json PATH: write the results there
  int reps = 0;            // --reps N (0: 15, or 7 in quick mode)
  int warmup = 1;          // --warmup N untimed repetitions per side before the timed ones
  std::string filter;      // --filter S: run only cases whose name contains S
  bool strict = false;     // --strict: exit 1 when a case misses its target ratio
};

// extra: the benchmark's own flags, one "  --flag ...  what\n" line each.
inline std::string usage_text(int default_reps, int default_quick_reps, const std::string& extra) {
  return "options:\n"
         "  --quick         fewer repetitions and smaller inputs (also VTSIM_BENCH_QUICK=1)\n"
         "  --json PATH     write results as JSON (schema vtsim-bench/1, docs/bench.md; directories are created)\n"
         "  --reps N        timed repetitions per side (default " +
         std::to_string(default_reps) + "; quick " + std::to_string(default_quick_reps) +
         ")\n"
         "  --warmup N      untimed repetitions per side first (default 1)\n"
         "  --filter S      only cases whose name contains S\n"
         "  --strict        exit 1 if a case misses its target ratio\n" +
         extra + "  --help          this text\n";
}

// Parses the common flags; on a usage error prints it and exits 2, on --help exits 0.
// default_reps / default_quick_reps: the repetitions when --reps is not given.
inline Options parse_options(const std::string& benchmark, int argc, char** argv, int default_reps = 15,
                             int default_quick_reps = 7, const std::string& extra_usage = "") {
  const std::string usage = usage_text(default_reps, default_quick_reps, extra_usage);
  Options o;
  if (const char* q = std::getenv("VTSIM_BENCH_QUICK"); q && std::string(q) != "" && std::string(q) != "0")
    o.quick = true;
  auto fail = [&](const std::string& msg) {
    std::cerr << "bench_" << benchmark << ": " << msg << "\n" << usage;
    std::exit(2);
  };
  auto int_arg = [&](int& i, const std::string& flag, int lo, int hi) {
    if (i + 1 >= argc) fail(flag + " needs a value");
    const std::string v = argv[++i];
    std::size_t used = 0;
    long long n = 0;
    try {
      n = std::stoll(v, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != v.size() || v.empty() || n < lo || n > hi)
      fail(flag + " '" + v + "': expected an integer in [" + std::to_string(lo) + ", " +
           std::to_string(hi) + "]");
    return static_cast<int>(n);
  };
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") o.quick = true;
    else if (a == "--strict") o.strict = true;
    else if (a == "--reps") o.reps = int_arg(i, a, 1, 100000);
    else if (a == "--warmup") o.warmup = int_arg(i, a, 0, 100000);
    else if (a == "--json" || a == "--filter") {
      if (i + 1 >= argc) fail(a + " needs a value");
      (a == "--json" ? o.json_path : o.filter) = argv[++i];
    } else if (a == "--help" || a == "-h") {
      std::cout << "bench_" << benchmark << " [options]\n" << usage;
      std::exit(0);
    } else {
      fail("unknown option '" + a + "'");
    }
  }
  if (o.reps == 0) o.reps = o.quick ? default_quick_reps : default_reps;
  return o;
}

namespace detail {
inline std::string read_first_line_with(const char* path, const std::string& prefix) {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(prefix, 0) == 0) {
      const auto colon = line.find(':');
      std::string v = colon == std::string::npos ? line : line.substr(colon + 1);
      v.erase(0, v.find_first_not_of(" \t"));
      return v;
    }
  return "";
}
inline std::string load_average() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  in >> a >> b >> c;
  return a.empty() ? "" : a + " " + b + " " + c;
}
inline std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}
inline nlohmann::json summary_json(const Summary& s) {
  return {{"median", s.median}, {"min", s.min}, {"max", s.max}, {"p10", s.p10},
          {"p90", s.p90},       {"mad", s.mad}, {"samples", s.samples}};
}
}  // namespace detail

// Facts about where a benchmark ran, for the JSON "machine" object.
inline nlohmann::json machine_info() {
  nlohmann::json m;
  char host[256] = {};
  gethostname(host, sizeof host - 1);
  m["hostname"] = host;
  m["cpu"] = detail::read_first_line_with("/proc/cpuinfo", "model name");
  m["logical_cores"] = std::thread::hardware_concurrency();
  utsname u{};
  if (uname(&u) == 0) m["os"] = std::string(u.sysname) + " " + u.release + " " + u.machine;
#if defined(__clang__)
  m["compiler"] = std::string("clang ") + __clang_version__;
#elif defined(__GNUC__)
  m["compiler"] = std::string("gcc ") + __VERSION__;
#endif
#if defined(__OPTIMIZE__)
  m["optimized"] = true;
#else
  m["optimized"] = false;
#endif
#if defined(NDEBUG)
  m["asserts"] = false;
#else
  m["asserts"] = true;
#endif
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  m["sanitized"] = true;
#else
  m["sanitized"] = false;
#endif
  m["load_average_start"] = detail::load_average();
  return m;
}

class Harness {
 public:
  // default_reps / default_quick_reps replace 15 / 7 for benchmarks whose repetition is costly
  // (a whole replay); extra_usage lists the benchmark's own flags in --help.
  Harness(std::string benchmark, int argc, char** argv, int default_reps = 15, int default_quick_reps = 7,
          const std::string& extra_usage = "")
      : name_(std::move(benchmark)),
        opt_(parse_options(name_, argc, argv, default_reps, default_quick_reps, extra_usage)),
        started_(detail::utc_now()),
        machine_(machine_info()) {
    std::cout << fmt::format("bench_{}: {} repetitions per side after {} warm-up{}\n", name_, opt_.reps,
                             opt_.warmup, opt_.quick ? " (quick)" : "");
  }

  const Options& options() const { return opt_; }
  bool quick() const { return opt_.quick; }
  // Input sizes: `full` normally, `quick_value` in quick mode.
  template <class T>
  T pick(T full, T quick_value) const {
    return opt_.quick ? quick_value : full;
  }
  bool selected(const std::string& case_name) const {
    return opt_.filter.empty() || case_name.find(opt_.filter) != std::string::npos;
  }
  // Benchmark-wide facts (input sizes, seeds) for the JSON "params" object.
  void param(const std::string& key, nlohmann::json value) { params_[key] = std::move(value); }

  // Measures one side alone. Returns nullptr when --filter skips the case; the pointer stays
  // valid for the harness's lifetime.
  const Result* run(const Case& c, const Side& ours) { return measure(c, ours, nullptr); }
  // Measures ours and the reference with interleaved repetitions (ours first on even
  // repetitions, the reference first on odd ones) so drift on a shared machine hits both alike.
  const Result* compare(const Case& c, const Side& ours, const Side& reference) {
    return measure(c, ours, &reference);
  }

  // Measures one side against a fixed reference value in the case's units that cannot be timed
  // side by side — the real time a replayed trace spans, for "× real time". The ratio of each
  // repetition is reference / ours (lower is better) or ours / reference (higher is better).
  const Result* run_against(const Case& c_in, const Side& ours, const std::string& ref_name, double ref_value) {
    const Case c = held(c_in);
    if (!selected(c.name)) return nullptr;
    quiet_ = true;
    measure(c, ours, nullptr);
    quiet_ = false;
    Result& r = results_.back();
    r.reference = ref_name;
    r.ref = summarize(std::vector<double>(r.ours.samples.size(), ref_value));
    const bool hib = higher_is_better(c.metric);
    for (double a : r.ours.samples) r.pair_ratios.push_back(hib ? a / ref_value : ref_value / a);
    std::vector<double> sorted = r.pair_ratios;
    std::sort(sorted.begin(), sorted.end());
    r.ratio = percentile_sorted(sorted, 0.5);
    r.ratio_of_medians = hib ? r.ours.median / ref_value : ref_value / r.ours.median;
    r.meets_target = c.target_ratio <= 0 || r.ratio >= c.target_ratio;
    print(r);
    return &r;
  }

  // Prints the summary, writes the JSON if asked. Returns the process exit code: 0; 1 when
  // --strict and a case missed its target; 2 when the JSON cannot be written.
  int finish() {
    bool missed = other_missed_;
    for (const Result& r : results_) missed |= !r.meets_target;
    if (!opt_.json_path.empty()) {
      std::error_code ec;  // e.g. out/bench/ before bench/run made it; a failure shows at the write
      if (const auto dir = std::filesystem::path(opt_.json_path).parent_path(); !dir.empty())
        std::filesystem::create_directories(dir, ec);
      std::ofstream out(opt_.json_path);
      out << to_json().dump(2) << "\n";
      out.close();
      if (!out) {
        std::cerr << "bench_" << name_ << ": cannot write " << opt_.json_path << "\n";
        return 2;
      }
      std::cout << "bench_" << name_ << ": wrote " << opt_.json_path << "\n";
    }
    if (missed) std::cout << "bench_" << name_ << ": some cases missed their target ratio\n";
    return missed && opt_.strict ? 1 : 0;
  }

  const std::deque<Result>& results() const { return results_; }

  // A benchmark's own check (an accuracy bound, not a ratio) missed: finish() says so, and exits 1
  // under --strict. Checks that quick mode cannot hold are not made there (see Case::target_in_quick).
  void missed_target() { other_missed_ = true; }

  // The case as measured in this mode: its target dropped in quick mode unless it holds there.
  Case held(const Case& c) const {
    Case h = c;
    if (opt_.quick && !c.target_in_quick) h.target_ratio = 0;
    return h;
  }

  // Records a comparison whose repetitions the benchmark measured itself, in the case's units —
  // for a reference that reports its own figures (fio's bandwidth and latency percentiles, which
  // exclude its process start-up). ours[i] and ref[i] must be the i-th repetitions of each side,
  // run back to back (alternating order), as compare() would; the ratio is computed the same way.
  const Result* add_measured(const Case& c_in, const std::string& ours_name, const std::vector<double>& ours,
                             const std::string& ref_name, const std::vector<double>& ref) {
    const Case c = held(c_in);
    if (!selected(c.name)) return nullptr;
    if (ours.empty() || ours.size() != ref.size()) {
      std::cerr << "bench_" << name_ << ": case '" << c.name << "' has unpaired repetitions\n";
      std::exit(3);
    }
    Result r;
    r.spec = c;
    r.side = ours_name;
    r.ours = summarize(ours);
    r.reference = ref_name;
    r.ref = summarize(ref);
    const bool hib = higher_is_better(c.metric);
    for (std::size_t i = 0; i < ours.size(); ++i) r.pair_ratios.push_back(hib ? ours[i] / ref[i] : ref[i] / ours[i]);
    std::vector<double> sorted = r.pair_ratios;
    std::sort(sorted.begin(), sorted.end());
    r.ratio = percentile_sorted(sorted, 0.5);
    r.ratio_of_medians = hib ? r.ours.median / r.ref.median : r.ref.median / r.ours.median;
    r.meets_target = c.target_ratio <= 0 || r.ratio >= c.target_ratio;
    print(r);
    results_.push_back(std::move(r));
    return &results_.back();
  }

  nlohmann::json to_json() const {
    nlohmann::json j;
    j["schema"] = "vtsim-bench/1";
    j["benchmark"] = name_;
    const char* git = std::getenv("VTSIM_GIT");
    j["git"] = git && *git ? git : "unknown";
    j["time_utc"] = started_;
    j["quick"] = opt_.quick;
    j["reps"] = opt_.reps;
    j["warmup"] = opt_.warmup;
    nlohmann::json m = machine_;
    m["load_average_end"] = detail::load_average();
    j["machine"] = m;
    j["params"] = params_;
    j["results"] = nlohmann::json::array();
    for (const Result& r : results_) {
      nlohmann::json e = detail::summary_json(r.ours);
      e["name"] = r.spec.name;
      e["side"] = r.side;
      e["unit"] = metric_unit(r.spec.metric);
      e["better"] = higher_is_better(r.spec.metric) ? "higher" : "lower";
      e["reps"] = r.ours.samples.size();
      e["work_per_rep"] = r.spec.work;
      e["params"] = r.spec.params;
      if (r.reference) {
        nlohmann::json ref = detail::summary_json(r.ref);
        ref["name"] = *r.reference;
        e["reference"] = ref;
        e["ratio"] = r.ratio;
        e["ratio_of_medians"] = r.ratio_of_medians;
        e["pair_ratios"] = r.pair_ratios;
      } else {
        e["reference"] = nullptr;
        e["ratio"] = nullptr;
        e["ratio_of_medians"] = nullptr;
        e["pair_ratios"] = nullptr;
      }
      e["target_ratio"] =
          r.spec.target_ratio > 0 ? nlohmann::json(r.spec.target_ratio) : nlohmann::json(nullptr);
      e["meets_target"] = r.meets_target;
      j["results"].push_back(e);
    }
    return j;
  }

 private:
  double value_of(const Case& c, double ns) const {
    const double s = ns * 1e-9;
    switch (c.metric) {
      case Metric::kNsPerOp: return ns / c.work;
      case Metric::kMsPerRep: return ns * 1e-6;
      case Metric::kMBPerS: return c.work / s / 1e6;
      case Metric::kOpsPerS: return c.work / s;
    }
    return ns;
  }

  static double time_once(const Side& side) {
    if (side.setup) side.setup();
    clobber_memory();
    const auto t0 = std::chrono::steady_clock::now();
    side.run();
    clobber_memory();
    const auto t1 = std::chrono::steady_clock::now();
    // Never 0, so rates stay finite even for a run below the clock's resolution.
    const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(t1 - t0).count();
    return std::max(1.0, static_cast<double>(ns));
  }

  const Result* measure(const Case& c_in, const Side& ours, const Side* ref) {
    const Case c = held(c_in);
    if (!selected(c.name)) return nullptr;
    if (!(c.work > 0) || !std::isfinite(c.work)) {
      std::cerr << "bench_" << name_ << ": case '" << c.name << "' has work " << c.work << " (must be > 0)\n";
      std::exit(3);
    }
    for (int i = 0; i < opt_.warmup; ++i) {
      time_once(ours);
      if (ref) time_once(*ref);
    }
    std::vector<double> a, b;
    double shortest_ns = 1e300;
    for (int i = 0; i < opt_.reps; ++i) {
      double ta = 0, tb = 0;
      if (ref && i % 2 == 1) {
        tb = time_once(*ref);
        ta = time_once(ours);
      } else {
        ta = time_once(ours);
        if (ref) tb = time_once(*ref);
      }
      shortest_ns = std::min(shortest_ns, ta);
      a.push_back(value_of(c, ta));
      if (ref) {
        shortest_ns = std::min(shortest_ns, tb);
        b.push_back(value_of(c, tb));
      }
    }
    Result r;
    r.spec = c;
    r.side = ours.name;
    r.ours = summarize(a);
    if (ref) {
      r.reference = ref->name;
      r.ref = summarize(b);
      const bool hib = higher_is_better(c.metric);
      for (std::size_t i = 0; i < a.size(); ++i) r.pair_ratios.push_back(hib ? a[i] / b[i] : b[i] / a[i]);
      std::vector<double> sorted = r.pair_ratios;
      std::sort(sorted.begin(), sorted.end());
      r.ratio = percentile_sorted(sorted, 0.5);
      r.ratio_of_medians = hib ? r.ours.median / r.ref.median : r.ref.median / r.ours.median;
    }
    r.meets_target = c.target_ratio <= 0 || (ref && r.ratio >= c.target_ratio);
    if (shortest_ns < 1e6)
      std::cerr << fmt::format(
          "bench_{}: warning: '{}' has repetitions of {:.0f} us; below 1 ms the clock and noise "
          "dominate: give it more work\n",
          name_, c.name, shortest_ns / 1e3);
    if (!quiet_) print(r);
    results_.push_back(std::move(r));
    return &results_.back();
  }

  bool quiet_ = false;

  static std::string num(double v) {
    if (v != 0 && (std::fabs(v) >= 1e6 || std::fabs(v) < 0.01)) return fmt::format("{:.3g}", v);
    return fmt::format("{:.{}f}", v, std::fabs(v) >= 100 ? 0 : std::fabs(v) >= 10 ? 1 : 2);
  }

  void print(const Result& r) const {
    const char* unit = metric_unit(r.spec.metric);
    std::string line = fmt::format("  {:<22} {:<10} {:>8} {} [p10 {} p90 {}]", r.spec.name, r.side,
                                   num(r.ours.median), unit, num(r.ours.p10), num(r.ours.p90));
    if (r.reference) {
      line += fmt::format("  vs {} {} {}  ratio {:.2f}x", *r.reference, num(r.ref.median), unit, r.ratio);
      if (r.spec.target_ratio > 0)
        line += fmt::format(" (target {:.2g}x{})", r.spec.target_ratio, r.meets_target ? "" : ", MISSED");
    }
    std::cout << line << std::endl;
  }

  std::string name_;
  Options opt_;
  std::string started_;
  nlohmann::json machine_;
  nlohmann::json params_ = nlohmann::json::object();
  std::deque<Result> results_;  // a deque: pointers handed out stay valid
  bool other_missed_ = false;  // missed_target() was called
};

}  // namespace vtsim::bench
