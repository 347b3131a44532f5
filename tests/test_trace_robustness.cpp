// Untrusted input, many times over: deterministic mutations of valid files (byte flips, cuts,
// insertions, duplicated and swapped lines) must either load into a valid trace or raise
// InputError -- never another exception, a crash or a hang (run under ASan/UBSan too). Also:
// the checked-in standard traces are exactly what the generators produce.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "sim/trace/trace_gen.h"
#include "sim/trace/trace_import.h"
#include "sim/trace/trace_io.h"
#include "trace_test_util.h"

using namespace vtsim;
using vtsim::test::ScratchDir;
using vtsim::test::write_file;

namespace {

// The whole lines within the first n bytes.
std::string head(const std::string& s, std::size_t n) { return s.substr(0, s.rfind('\n', n) + 1); }

struct Rng {  // splitmix64: a fixed sequence, so every run tests the same mutations
  std::uint64_t s;
  std::uint64_t next() {
    std::uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  std::size_t below(std::size_t n) { return n ? static_cast<std::size_t>(next() % n) : 0; }
};

std::string mutate(std::string text, Rng& r) {
  static const char* kTokens[] = {"nan", "inf", "-", ",", " ", "\r", "\n", "\t", "1e308", "1e-320", "#",
                                  "\xff", "\xc3\xa9", "0x1p3", "+", "..", "e", "18446744073709551616"};
  const int edits = 1 + static_cast<int>(r.below(4));
  for (int k = 0; k < edits && !text.empty(); ++k) {
    const std::size_t at = r.below(text.size());
    switch (r.below(6)) {
      case 0: text[at] = static_cast<char>(r.below(256)); break;
      case 1: text.resize(at); break;
      case 2: text.insert(at, kTokens[r.below(std::size(kTokens))]); break;
      case 3: text.erase(at, 1 + r.below(20)); break;
      case 4: {  // duplicate a stretch (often whole lines: repeated or out-of-order times)
        const std::size_t len = 1 + r.below(200);
        text.insert(r.below(text.size()), text.substr(at, len));
        break;
      }
      default: text[at] = "0123456789.-,"[r.below(13)]; break;
    }
  }
  return text;
}

template <class Load>
void fuzz(const std::string& seed_text, const std::string& path, int rounds, std::uint64_t seed, Load load) {
  Rng r{seed};
  int ok = 0, refused = 0;
  for (int i = 0; i < rounds; ++i) {
    // A fresh name each round: rewriting one file in place makes ext4 flush it on every close.
    const std::string file = path + "." + std::to_string(i);
    write_file(file, mutate(seed_text, r));
    try {
      const Trace t = load(file);
      validate_trace(t, "fuzz");  // whatever loads satisfies the invariants
      ++ok;
    } catch (const InputError&) {
      ++refused;
    }
    std::filesystem::remove(file);
  }
  // Both outcomes occur (the mutations are neither all harmless nor all fatal).
  CHECK(ok > 0);
  CHECK(refused > 0);
  MESSAGE(path << ": " << ok << " loaded, " << refused << " refused");
}

}  // namespace

TEST_CASE("mutated native, TUM, EuRoC and KITTI files load validly or raise InputError") {
  ScratchDir dir;
  TraceGenParams p = default_gen_params("turn");
  p.duration_s = 1.0;
  p.event_s = 0.5;
  const std::string native = format_trace(generate_trace(p));
  fuzz(native, dir.file("n.csv"), 600, 1, [](const std::string& f) { return load_trace(f); });
  fuzz(native, dir.file("a.csv"), 300, 2, [](const std::string& f) { return load_any_trace(f); });
  const std::string data = VTSIM_TEST_DATA;
  const std::string tum = head(vtsim::test::slurp(data + "/tum_fr2_desk_excerpt.txt"), 3000);
  ImportOptions tum_o;
  tum_o.format = "tum";
  fuzz(tum, dir.file("t.txt"), 600, 3, [&](const std::string& f) { return import_trace(f, tum_o); });
  const std::string euroc = head(vtsim::test::slurp(data + "/euroc_V1_02_excerpt.csv"), 4000);
  ImportOptions euroc_o;
  euroc_o.format = "euroc";
  fuzz(euroc, dir.file("e.csv"), 600, 4, [&](const std::string& f) { return import_trace(f, euroc_o); });
  const std::string kitti = vtsim::test::slurp(data + "/kitti_synthetic_poses.txt");
  ImportOptions kitti_o;
  kitti_o.format = "kitti";
  kitti_o.kitti_rate_hz = 10.0;
  fuzz(kitti, dir.file("k.txt"), 600, 5, [&](const std::string& f) { return import_trace(f, kitti_o); });
}

TEST_CASE("the standard traces in traces/ are what scripts/gen_traces.sh generates") {
  for (const TraceGenerator& k : trace_generators().entries()) {
    const std::string path = std::string(VTSIM_SOURCE_DIR) + "/traces/" + std::string(k.name) + ".csv";
    CAPTURE(path);
    CHECK(vtsim::test::slurp(path) == format_trace(generate_trace(default_gen_params(k.name))));
  }
}
