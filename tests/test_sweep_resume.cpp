// A sweep's resume reuses only what is still valid (docs/sweep.md, "Resume"): an input that
// changed (a scene file, a trace, the build) is refused by name or its rows re-run; failed rows
// are retried; a second sweep on an output in use is refused, and a killed one leaves no lock.
#include <doctest/doctest.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include <fmt/format.h>

#include "core/error.h"
#include "sim/sweep/sweep.h"
#include "store_test_util.h"
#include "test_util.h"

using namespace vtsim;

namespace {

void resume_write(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

// A ground quad of side `m` metres at z = 0 whose UVs span the whole texture.
std::string resume_quad_obj(double m) {
  return fmt::format("v 0 0 0\nv {0} 0 0\nv {0} {0} 0\nv 0 {0} 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n", m);
}

std::string resume_error(const SweepSpec& spec, const SweepOptions& o) {
  try {
    run_sweep(spec, o);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("sweep resume: an edited OBJ is refused by name, --rerun-changed re-runs its rows and gives a fresh run's") {
  test::TempDir d;
  resume_write(d.file("q.obj"), resume_quad_obj(200.0));
  resume_write(d.file("spec.toml"), "set = [\"scene.kind=mesh\", \"scene.file=" + d.file("q.obj") +
                                        "\", \"texture.width=65536\", \"texture.height=65536\", \"view.divisor=16\"]\n"
                                        "generate = [\"walk duration_s=1 start_m=20,20 height_m=2\"]\n"
                                        "[grid]\n\"upload.tiles_per_frame\" = [2, 8]\n");
  const SweepSpec spec = load_sweep_spec(d.file("spec.toml"));
  SweepOptions o;
  o.out_dir = d.file("out");
  o.jobs = 1;
  SweepRunStats st = run_sweep(spec, o);
  REQUIRE(st.rows == 2);
  REQUIRE(st.rows_failed == 0);
  const std::string before = test::slurp(o.out_dir + "/rows.jsonl");
  // Unchanged: everything is reused.
  st = run_sweep(spec, o);
  CHECK(st.rows_skipped == 2);
  CHECK(test::slurp(o.out_dir + "/rows.jsonl") == before);

  // The OBJ edited: the same sweep on the same -o is refused, naming the file; nothing changes.
  resume_write(d.file("q.obj"), resume_quad_obj(30.0));
  const std::string err = resume_error(spec, o);
  CHECK(test::contains(err, "scene.file " + d.file("q.obj") + " changed since " + o.out_dir +
                                " was written; use a new -o or --rerun-changed"));
  CHECK(test::slurp(o.out_dir + "/rows.jsonl") == before);

  // --rerun-changed: both rows run again, and the outputs are a fresh -o's, byte for byte.
  o.rerun_changed = true;
  st = run_sweep(spec, o);
  CHECK(st.rows_skipped == 0);
  CHECK(st.rows_changed == 2);
  SweepOptions fresh = o;
  fresh.out_dir = d.file("fresh");
  run_sweep(spec, fresh);
  const std::string after = test::slurp(o.out_dir + "/rows.jsonl");
  CHECK(after == test::slurp(fresh.out_dir + "/rows.jsonl"));
  CHECK(after != before);
  CHECK(test::slurp(o.out_dir + "/rows.csv") == test::slurp(fresh.out_dir + "/rows.csv"));
}

TEST_CASE("sweep resume: an OBJ read through assimp names its .mtl as an input, and an edited .mtl is refused") {
  test::TempDir d;
  resume_write(d.file("m.obj"), "mtllib m.mtl\nusemtl m\n" + resume_quad_obj(200.0));
  resume_write(d.file("m.mtl"), "newmtl m\nKd 1 1 1\n");
  resume_write(d.file("spec.toml"), "set = [\"scene.kind=mesh\", \"scene.file=" + d.file("m.obj") +
                                        "\", \"scene.mesh_loader=assimp\", \"view.divisor=32\"]\n"
                                        "generate = [\"walk duration_s=1 start_m=20,20 height_m=2\"]\n");
  const SweepSpec spec = load_sweep_spec(d.file("spec.toml"));
  SweepOptions o;
  o.out_dir = d.file("out");
  o.jobs = 1;
  run_sweep(spec, o);
  const nlohmann::json shard = nlohmann::json::parse(test::slurp(o.out_dir + "/shard.json"));
  const std::string name = "scene.file " + d.file("m.obj") + " (assimp)";
  REQUIRE(shard["inputs"].contains(name));
  CHECK(shard["inputs"][name]["files"] == nlohmann::json::array({d.file("m.obj"), d.file("m.mtl")}));
  resume_write(d.file("m.mtl"), "newmtl m\nKd 1 0 1\n");
  CHECK(test::contains(resume_error(spec, o), name + " changed since"));
}

TEST_CASE("sweep resume: only the tasks that read a changed trace re-run, and a build change is named") {
  test::TempDir d;
  std::filesystem::copy_file(std::string(VTSIM_SOURCE_DIR) + "/traces/walk.csv", d.file("a.csv"));
  std::filesystem::copy_file(std::string(VTSIM_SOURCE_DIR) + "/traces/walk.csv", d.file("b.csv"));
  resume_write(d.file("spec.toml"), "set = [\"view.divisor=32\"]\ntraces = [\"a.csv\", \"b.csv\"]\n"
                                    "[grid]\n\"upload.tiles_per_frame\" = [4]\n");
  const SweepSpec spec = load_sweep_spec(d.file("spec.toml"));
  SweepOptions o;
  o.out_dir = d.file("out");
  o.jobs = 1;
  run_sweep(spec, o);
  // b.csv loses its last pose: trace 1 changed, trace 0 did not.
  std::string b = test::slurp(d.file("b.csv"));
  b.erase(b.find_last_of('\n', b.size() - 2) + 1);
  resume_write(d.file("b.csv"), b);
  const SweepSpec spec2 = load_sweep_spec(d.file("spec.toml"));
  const std::string err = resume_error(spec2, o);
  CAPTURE(err);
  CHECK(test::contains(err, "trace 1 (" + d.file("b.csv") + ") changed since"));
  o.rerun_changed = true;
  const SweepRunStats st = run_sweep(spec2, o);
  CHECK(st.rows_skipped == 1);
  CHECK(st.rows_changed == 1);
  SweepOptions fresh = o;
  fresh.out_dir = d.file("fresh");
  run_sweep(spec2, fresh);
  CHECK(test::slurp(o.out_dir + "/rows.jsonl") == test::slurp(fresh.out_dir + "/rows.jsonl"));

  // Rows made by another build (shard.json records it): refused, naming both builds.
  nlohmann::json shard = nlohmann::json::parse(test::slurp(o.out_dir + "/shard.json"));
  shard["inputs"]["build"]["hash"] = "0000000000000000";
  shard["inputs"]["build"]["what"] = "vtsim 0.0.1 commit 0123456789ab (old)";
  shard["spec_hash"] = "0000000000000000";
  resume_write(o.out_dir + "/shard.json", shard.dump(2));
  for (const auto& f : std::filesystem::directory_iterator(o.out_dir + "/parts")) {  // and its parts
    const std::string text = test::slurp(f.path().string());
    nlohmann::json head = nlohmann::json::parse(text.substr(0, text.find('\n')));
    head["spec_hash"] = "0000000000000000";
    head["inputs"] = "0000000000000000";
    resume_write(f.path().string(), head.dump() + text.substr(text.find('\n')));
  }
  o.rerun_changed = false;
  CHECK(test::contains(resume_error(spec2, o), "build (its rows were made by vtsim 0.0.1 commit 0123456789ab (old); this is vtsim "));
  o.rerun_changed = true;
  CHECK(run_sweep(spec2, o).rows_changed == 2);
}

TEST_CASE("sweep resume: a failed row is retried and still counted failed") {
  test::TempDir d;
  resume_write(d.file("spec.toml"), "generate = [\"walk duration_s=1\"]\n[[configs]]\n[[configs]]\n"
                                    "\"scene.kind\" = \"heightfield\"\n\"scene.file\" = \"" + d.file("h.png") + "\"\n");
  const SweepSpec spec = load_sweep_spec(d.file("spec.toml"));
  SweepOptions o;
  o.out_dir = d.file("out");
  o.jobs = 1;
  SweepRunStats st = run_sweep(spec, o);
  CHECK(st.rows_failed == 1);
  st = run_sweep(spec, o);  // before: "1 already done, 0 failed"
  CHECK(st.rows_skipped == 1);
  CHECK(st.rows_retried == 1);
  CHECK(st.rows_failed == 1);
  test::CliRun r = test::run_vtsim_capture("sweep " + d.file("spec.toml") + " -o " + o.out_dir + " --jobs 1", d.file("err"));
  CHECK(r.code == 1);
  CHECK(test::contains(r.out, "2 rows (1 run now, 1 already done, 1 failed)"));
}

TEST_CASE("sweep resume: a second sweep on an output in use is refused, and a killed holder leaves no lock") {
  test::TempDir d;
  resume_write(d.file("spec.toml"), "set = [\"view.divisor=32\"]\ngenerate = [\"walk duration_s=1\"]\n");
  const SweepSpec spec = load_sweep_spec(d.file("spec.toml"));
  SweepOptions o;
  o.out_dir = d.file("out");
  o.jobs = 1;
  std::filesystem::create_directories(o.out_dir);
  // Another process holds the output's lock, as a running sweep does.
  int ready[2];
  REQUIRE(::pipe(ready) == 0);
  const pid_t pid = ::fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    const int fd = ::open((o.out_dir + "/sweep.lock").c_str(), O_RDWR | O_CREAT, 0644);
    if (fd < 0 || ::flock(fd, LOCK_EX) != 0) ::_exit(3);
    if (::write(ready[1], "x", 1) != 1) ::_exit(4);
    for (;;) ::pause();
  }
  char c = 0;
  REQUIRE(::read(ready[0], &c, 1) == 1);
  ::close(ready[0]);
  ::close(ready[1]);
  const std::string err = resume_error(spec, o);
  CHECK(test::contains(err, "in use by another vtsim sweep or merge"));
  CHECK_FALSE(std::filesystem::exists(o.out_dir + "/shard.json"));
  CHECK(test::contains(resume_error(spec, o), "give this sweep another -o"));
  // Killed: the kernel drops its lock; the same -o runs.
  ::kill(pid, SIGKILL);
  int status = 0;
  ::waitpid(pid, &status, 0);
  CHECK(WIFSIGNALED(status));
  CHECK(resume_error(spec, o) == "");
  CHECK(std::filesystem::exists(o.out_dir + "/rows.jsonl"));
  // A merge into an output in use is refused the same way.
  const int fd = ::open((o.out_dir + "/sweep.lock").c_str(), O_RDWR);
  REQUIRE(fd >= 0);
  REQUIRE(::flock(fd, LOCK_EX) == 0);
  CHECK_THROWS_WITH_AS(merge_sweep({o.out_dir}, o.out_dir), doctest::Contains("in use by another vtsim sweep"), InputError);
  ::close(fd);
}
