// No output lost (docs/robustness.md "Outputs"): every file vtsim writes goes to a temporary beside
// it and is renamed into place only once complete. A command that fails leaves an existing output
// byte for byte as it was and no temporary behind; one killed with SIGKILL mid-write leaves the old
// bytes too. Plus the output-directory rule (the last level is created, a missing parent refused).
#include <doctest/doctest.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "core/atomic_file.h"
#include "core/error.h"
#include "store_test_util.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;

void oa_write(const std::string& path, const std::string& text) {
  fs::create_directories(fs::path(path).parent_path());
  std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
}

// The temporaries (".NAME.tmp-XXXXXX") left anywhere under `dir`.
std::vector<std::string> oa_temps(const std::string& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (vtsim::is_atomic_temp_name(e.path().filename().string())) out.push_back(e.path().string());
  return out;
}

// `sh -c SCRIPT` with $V the CLI, $D the test directory and $SRC the source tree.
vtsim::test::CliRun oa_sh(const std::string& dir, const std::string& script) {
  return vtsim::test::run_capture("V=" + std::string(VTSIM_CLI) + " D=" + dir + " SRC=" + std::string(VTSIM_SOURCE_DIR) +
                                      " sh -c '" + script + "' 2>" + dir + "/.err",
                                  dir + "/.err");
}

}  // namespace

TEST_CASE("atomic file: written whole on commit, and without it the target stays and no temporary is left") {
  vtsim::test::TempDir d;
  const std::string p = d.file("out.txt");
  oa_write(p, "old");
  {
    vtsim::AtomicFile f(p);
    f.write("new, half");
    CHECK(vtsim::test::slurp(p) == "old");  // nothing is visible before the commit
    CHECK(vtsim::is_atomic_temp_name(fs::path(f.temp_path()).filename().string()));
  }  // an exception on its way: no commit
  CHECK(vtsim::test::slurp(p) == "old");
  CHECK(oa_temps(d.path.string()).empty());
  vtsim::write_file_atomic(p, "new");
  CHECK(vtsim::test::slurp(p) == "new");
  CHECK(oa_temps(d.path.string()).empty());
  // A writer that throws part way through (write_file_atomic_via): the target is untouched.
  CHECK_THROWS_AS(vtsim::write_file_atomic_via(p, [](const std::string& t) {
                    std::ofstream(t) << "partial";
                    throw vtsim::InputError(t, "failed part way");
                  }),
                  vtsim::InputError);
  CHECK(vtsim::test::slurp(p) == "new");
  CHECK(oa_temps(d.path.string()).empty());
  // keep_extension: the temporary ends like the target (image writers pick the format by it).
  vtsim::write_file_atomic_via(d.file("a.png"), [](const std::string& t) {
    CHECK(fs::path(t).extension() == ".png");
    std::ofstream(t) << "x";
  }, /*keep_extension=*/true);
  CHECK(vtsim::test::slurp(d.file("a.png")) == "x");
  // A symbolic link is written through (the link stays); /dev/null is written in place.
  oa_write(d.file("real.txt"), "old");
  fs::create_symlink(d.file("real.txt"), d.file("link.txt"));
  vtsim::write_file_atomic(d.file("link.txt"), "through");
  CHECK(fs::is_symlink(d.file("link.txt")));
  CHECK(vtsim::test::slurp(d.file("real.txt")) == "through");
  vtsim::write_file_atomic("/dev/null", "nothing");
  CHECK(fs::exists("/dev/null"));
  CHECK_FALSE(fs::is_regular_file("/dev/null"));
  // A missing directory: an error naming the target, nothing created.
  CHECK_THROWS_WITH_AS(vtsim::write_file_atomic(d.file("no/such/x.txt"), "x"), doctest::Contains("cannot create"),
                       vtsim::InputError);
}

TEST_CASE("outputs: every command that writes, failing on a bad input, leaves the existing outputs byte for byte") {
  vtsim::test::TempDir td;
  const std::string D = td.path.string();
  // Inputs: a short valid trace, a broken one, an empty access file, a file that is no JSON summary.
  oa_write(D + "/in/bad.csv", "# vtsim-trace v1\nt_s,x_m\nnot a trace\n");
  REQUIRE(oa_sh(D, "$V trace gen walk --duration 1 -o $D/in/walk.csv").code == 0);
  oa_write(D + "/in/empty.txt", "");
  oa_write(D + "/in/bad.json", "{\"not\": \"a summary\"}\n");
  oa_write(D + "/in/bad.toml", "[grid\n");
  oa_write(D + "/in/bad.png", "not an image");
  struct Case {
    std::string cmd;
    std::vector<std::string> outputs;  // relative to $D
  };
  const std::vector<Case> cases = {
      {"report $D/in/bad.json -o $D/o/prev.html", {"o/prev.html"}},
      {"replay --trace $D/in/bad.csv --summary $D/o/s.json --frames $D/o/f.csv --report $D/o/r.html",
       {"o/s.json", "o/f.csv", "o/r.html"}},
      {"replay --trace $D/in/walk.csv --set view.divisor=0 --summary $D/o/s.json", {"o/s.json"}},
      {"trace gen walk --duration -1 -o $D/o/t.csv", {"o/t.csv"}},
      {"trace import $D/in/bad.csv -o $D/o/t.csv", {"o/t.csv"}},
      {"trace export $D/in/bad.csv --format tum -o $D/o/t.txt", {"o/t.txt"}},
      {"trace resample $D/in/walk.csv --fps -5 -o $D/o/t.csv", {"o/t.csv"}},
      {"trace cut $D/in/walk.csv --from 0.5 --to 0.2 -o $D/o/t.csv", {"o/t.csv"}},
      {"trace level-walk $D/in/bad.json --mesh $D/in/bad.json -o $D/o/t.csv", {"o/t.csv"}},
      {"store gen -o $D/o/s.vts --size 0x0", {"o/s.vts"}},
      {"store build $D/in/bad.png -o $D/o/s.vts", {"o/s.vts"}},
      {"store extract $D/in/bad.png -o $D/o/x.png", {"o/x.png"}},
      {"mrc --accesses $D/in/empty.txt --json-file $D/o/m.json --csv $D/o/m.csv --svg $D/o/m.svg",
       {"o/m.json", "o/m.csv", "o/m.svg"}},
      {"mrc --trace $D/in/bad.csv --record $D/o/a.txt", {"o/a.txt"}},
      {"calibrate --samples $D/in/bad.csv -o $D/o/p.toml", {"o/p.toml"}},
      {"atlas build $D/in/bad.png --out $D/o/atlas", {"o/atlas/atlas.json", "o/atlas/atlas_level0.png"}},
      {"view --scene mesh --obj $D/in/bad.png -o $D/o/v.png", {"o/v.png"}},
      {"vt compare --traces $D/in/bad.csv --markdown $D/o/c.md --json-file $D/o/c.json", {"o/c.md", "o/c.json"}},
      {"sweep $D/in/bad.toml -o $D/o/sw", {"o/sw/rows.csv", "o/sw/report.html"}},
      {"sweep merge -o $D/o/mg $D/in", {"o/mg/rows.csv"}},
      {"tune $D/in/bad.toml -o $D/o/tu", {"o/tu/tune.json"}},
  };
  for (const Case& c : cases) {
    CAPTURE(c.cmd);
    for (const std::string& o : c.outputs) oa_write(D + "/" + o, "old bytes of " + o + "\n");
    const auto r = oa_sh(D, "$V " + c.cmd);
    CAPTURE(r.err);
    CHECK(r.code == 2);
    CHECK(vtsim::test::contains(r.err, "vtsim: error: "));
    for (const std::string& o : c.outputs) CHECK(vtsim::test::slurp(D + "/" + o) == "old bytes of " + o + "\n");
    CHECK(oa_temps(D).empty());
  }
}

namespace {

// Starts `vtsim ARGS` (no shell, no spaces inside an argument), waits until a temporary of
// `target` shows in its directory (the write has begun) or the target changes, or, with
// after_ms > 0, that long; then SIGKILLs it. True when it was killed then (not ended before).
bool oa_kill_mid_write(const std::vector<std::string>& args, const std::string& target, int after_ms = 0) {
  const std::string before = vtsim::test::slurp(target);
  const pid_t pid = ::fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    std::vector<char*> argv{const_cast<char*>(VTSIM_CLI)};
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    const int null = ::open("/dev/null", O_WRONLY);
    ::dup2(null, 1);
    ::dup2(null, 2);
    ::execv(VTSIM_CLI, argv.data());
    ::_exit(127);
  }
  const fs::path dir = fs::path(target).parent_path();
  std::string prefix = ".";  // (built in steps: GCC 12's -Wrestrict misfires on "." + string)
  prefix += fs::path(target).filename().string();
  prefix += ".tmp-";
  bool seen = false;
  if (after_ms > 0) {
    std::this_thread::sleep_for(std::chrono::milliseconds(after_ms));
    seen = true;
  }
  for (int i = 0; i < 20000 && !seen; ++i) {  // 20 s at most (sanitizer builds)
    for (const auto& e : fs::directory_iterator(dir)) seen |= e.path().filename().string().rfind(prefix, 0) == 0;
    if (!seen && vtsim::test::slurp(target) != before) break;  // written in place: the bug this catches
    int status = 0;
    if (!seen && ::waitpid(pid, &status, WNOHANG) == pid) return false;  // it ended first
    if (!seen) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ::kill(pid, SIGKILL);
  int status = 0;
  ::waitpid(pid, &status, 0);
  return seen && WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
}

}  // namespace

TEST_CASE("outputs: a command killed with SIGKILL while it writes leaves the existing output byte for byte") {
  vtsim::test::TempDir td;
  const std::string D = td.path.string();
  // A trace written as it is formatted (a streamed text writer): 3 hours at 60 Hz, ~80 MB.
  oa_write(D + "/t.csv", "old trace\n");
  CHECK(oa_kill_mid_write({"trace", "gen", "walk", "--duration", "10800", "-o", D + "/t.csv"}, D + "/t.csv"));
  CHECK(vtsim::test::slurp(D + "/t.csv") == "old trace\n");
  // A store (a large binary writer, positioned writes).
  oa_write(D + "/s.vts", "old store\n");
  CHECK(oa_kill_mid_write({"store", "gen", "-o", D + "/s.vts", "--size", "16384x16384", "--threads", "1"}, D + "/s.vts"));
  CHECK(vtsim::test::slurp(D + "/s.vts") == "old store\n");
  // A replay killed while it runs (its outputs are written at the end, each whole).
  REQUIRE(oa_sh(D, "$V trace gen walk --duration 600 -o $D/long.csv").code == 0);
  oa_write(D + "/f.csv", "old frames\n");
  oa_write(D + "/s.json", "old summary\n");
  CHECK(oa_kill_mid_write({"replay", "--trace", D + "/long.csv", "--frames", D + "/f.csv", "--summary", D + "/s.json", "-q"},
                          D + "/f.csv", 300));
  CHECK(vtsim::test::slurp(D + "/f.csv") == "old frames\n");
  CHECK(vtsim::test::slurp(D + "/s.json") == "old summary\n");
}

TEST_CASE("outputs: an output directory's last level is created, a missing parent refused, alike everywhere") {
  vtsim::test::TempDir td;
  const std::string D = td.path.string();
  oa_write(D + "/spec.toml", "generate = [\"walk duration_s=1\"]\n[[configs]]\n");
  REQUIRE(oa_sh(D, "$V trace gen walk --duration 1 -o $D/w.csv").code == 0);
  for (const std::string cmd : {"sweep $D/spec.toml -o $D/missing/x", "tune $D/spec.toml -o $D/missing/x",
                                "sweep merge -o $D/missing/x $D/spec.toml", "atlas build $D/w.csv --out $D/missing/x"}) {
    CAPTURE(cmd);
    const auto r = oa_sh(D, "$V " + cmd);
    CHECK(r.code == 2);
    CHECK(vtsim::test::contains(r.err, "/missing/x': the directory '" + D + "/missing' does not exist"));
    CHECK_FALSE(fs::exists(D + "/missing"));
  }
  // An existing file where the directory should be.
  oa_write(D + "/file", "x");
  const auto f = oa_sh(D, "$V sweep $D/spec.toml -o $D/file");
  CHECK(f.code == 2);
  CHECK(vtsim::test::contains(f.err, "'" + D + "/file' exists and is not a directory"));
  // The last level is created.
  const auto ok = oa_sh(D, "$V sweep $D/spec.toml -o $D/new -q --jobs 1");
  CHECK(ok.code == 0);
  CHECK(fs::is_regular_file(D + "/new/rows.csv"));
}
