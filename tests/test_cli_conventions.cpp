// The CLI's shared conventions (issue 26 §4-6, README.md "Conventions"): warnings that -q never
// hides and --werror turns into exit 1; "-" for stdin and stdout; outputs and parameters checked
// before the work; `vtsim help CMD`; bash completion generated from the commands; every error
// "vtsim: error:" naming the flag typed; vt compare's standard traces found beside the executable.
#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

#include "test_util.h"

namespace {

// `sh -c SCRIPT` with $V the CLI and $SRC the source tree: stdout captured, stderr in r.err.
vtsim::test::CliRun conv_sh(const std::string& script) {
  // One file per process: ctest runs the test cases as parallel processes.
  const std::string err =
      (std::filesystem::temp_directory_path() / ("vtsim_conv_err_" + std::to_string(getpid()) + ".txt")).string();
  return vtsim::test::run_capture("V=" + std::string(VTSIM_CLI) + " SRC=" + std::string(VTSIM_SOURCE_DIR) + " sh -c '" + script + "' 2>" + err,
                                  err);
}

std::string conv_tmp(const std::string& name) {
  const auto d = std::filesystem::temp_directory_path() / ("vtsim_conv_" + std::to_string(getpid()));
  std::filesystem::create_directories(d);
  return (d / name).string();
}

}  // namespace

TEST_CASE("cli: -q hides information, never a warning, and --werror turns a warning into exit 1") {
  // The camera far from the texture: "no frame saw a textured surface".
  const std::string far = "$V replay --trace $SRC/traces/static.csv --set run.fps=2 --set texture.origin_x_m=10000000";
  const auto quiet = conv_sh(far + " -q");
  CHECK(quiet.code == 0);
  CHECK(quiet.out.empty());
  CHECK(vtsim::test::contains(quiet.err, "vtsim: warning: no frame saw a textured surface"));
  const auto werror = conv_sh(far + " -q --werror");
  CHECK(werror.code == 1);
  CHECK(vtsim::test::contains(werror.err, "vtsim: warning: no frame saw"));
  CHECK(vtsim::test::contains(werror.err, "vtsim: error: 1 warning printed and --werror given"));
  const auto global = conv_sh("$V --werror replay --trace $SRC/traces/static.csv --set run.fps=2 --set texture.origin_x_m=10000000 -q");
  CHECK(global.code == 1);
  // No warning: --werror changes nothing.
  const auto clean = conv_sh("$V replay --trace $SRC/traces/static.csv --set run.fps=2 -q --werror");
  CHECK(clean.code == 0);
  CHECK(clean.err.empty());
}

TEST_CASE("cli: outputs in a missing directory are refused before the replay, naming the flag") {
  for (const std::string flag : {"--summary", "--frames", "--report"}) {
    const auto r = conv_sh("$V replay --trace $SRC/traces/static.csv " + flag + " /nonexistent_vtsim_dir/out");
    CHECK(r.code == 2);
    CHECK(vtsim::test::contains(r.err, "vtsim: error: " + flag + ": '/nonexistent_vtsim_dir/out': the directory '/nonexistent_vtsim_dir' does not exist"));
    CHECK(r.out.empty());  // nothing ran
  }
  // A missing store is named before the trace is even read.
  const auto store = conv_sh("$V replay --clock real --store /nonexistent_vtsim_dir/s.vts --trace $SRC/traces/static.csv");
  CHECK(store.code == 2);
  CHECK(vtsim::test::contains(store.err, "vtsim: error: --store: '/nonexistent_vtsim_dir/s.vts': cannot open for reading"));
  // calibrate: the output before the store and the measurements.
  const auto cal = conv_sh("$V calibrate --store /nonexistent_vtsim_dir/s.vts -o /nonexistent_vtsim_dir/p.toml");
  CHECK(cal.code == 2);
  CHECK(vtsim::test::contains(cal.err, "vtsim: error: --output: '/nonexistent_vtsim_dir/p.toml': the directory"));
}

TEST_CASE("cli: '-' is stdout for --frames and --summary, stdin for --trace and trace commands") {
  const std::string dir = conv_tmp("dash");
  std::filesystem::create_directories(dir);
  std::filesystem::remove(dir + "/-");
  const auto frames = conv_sh("cd " + dir + " && $V replay --trace $SRC/traces/static.csv --set run.fps=2 --frames - -q");
  CHECK(frames.code == 0);
  CHECK(frames.out.rfind("frame,t_s,clamp,bias,", 0) == 0);
  CHECK_FALSE(std::filesystem::exists(dir + "/-"));  // no file named "-"
  // The same replay from stdin: the same summary as from the file.
  const auto from_file = conv_sh("$V replay --trace $SRC/traces/static.csv --set run.fps=2 --summary - -q");
  const auto from_stdin = conv_sh("$V replay --trace - --set run.fps=2 --summary - -q < $SRC/traces/static.csv");
  CHECK(from_file.code == 0);
  CHECK(from_stdin.code == 0);
  CHECK(vtsim::test::contains(from_file.out, "\"bandwidth\""));
  const auto strip_wall = [](const std::string& s) { return s.substr(0, s.find("\"run\"")); };  // wall-clock figures differ
  CHECK(strip_wall(from_file.out) == strip_wall(from_stdin.out));
  // Two outputs on stdout are refused up front.
  const auto two = conv_sh("$V replay --trace $SRC/traces/static.csv --frames - --summary -");
  CHECK(two.code == 2);
  CHECK(vtsim::test::contains(two.err, "only one of --json, --summary -, --frames -, --report -, --produce-samples - can write to stdout"));
  // trace info from stdin; an error names "-", not a temporary file.
  const auto info = conv_sh("$V trace info - < $SRC/traces/walk.csv");
  CHECK(info.code == 0);
  CHECK(vtsim::test::contains(info.out, "file:          - (native"));
  const auto empty = conv_sh("$V trace info - < /dev/null");
  CHECK(empty.code == 2);
  CHECK(vtsim::test::contains(empty.err, "vtsim: error: -:1: "));
  CHECK_FALSE(vtsim::test::contains(empty.err, "vtsim-stdin"));
}

TEST_CASE("cli: vtsim help CMD prints the same help as vtsim CMD --help") {
  const auto help = conv_sh("$V help vt compare");
  const auto flag = conv_sh("$V vt compare --help");
  CHECK(help.code == 0);
  CHECK(help.out == flag.out);
  CHECK(vtsim::test::contains(help.out, "--policies"));
  CHECK(conv_sh("$V help replay").out == conv_sh("$V replay --help").out);
  const auto bad = conv_sh("$V help nosuch");
  CHECK(bad.code == 2);
  CHECK(vtsim::test::contains(bad.err, "vtsim: error: help: no command 'nosuch'"));
}

TEST_CASE("cli: the bash completion lists every subcommand and option, generated from the commands") {
  const std::string script = conv_tmp("completion.bash");
  REQUIRE(conv_sh("$V completion bash > " + script).code == 0);
  // Every subcommand `vtsim --help` lists, in the completion's top level; nested ones too.
  const auto top = conv_sh("bash -c \". " + script + "; echo \\${_vtsim_subs[vtsim]}\"");
  const auto help = conv_sh("$V --help | sed -n \"/^Subcommands:/,\\$p\" | awk \"NR>1 {print \\$1}\"");
  REQUIRE(!help.out.empty());
  std::size_t listed = 0;
  for (std::size_t b = 0; b < help.out.size();) {
    const std::size_t e = help.out.find('\n', b);
    const std::string name = help.out.substr(b, e - b);
    b = e == std::string::npos ? help.out.size() : e + 1;
    if (name.empty()) continue;
    const bool in_top = vtsim::test::contains(" " + top.out, " " + name + " ") || vtsim::test::contains(" " + top.out, " " + name + "\n");
    CHECK_MESSAGE(in_top, name);
    ++listed;
  }
  CHECK(listed >= 12);
  const auto vt = conv_sh("bash -c \". " + script + "; echo \\${_vtsim_subs[\\\"vtsim vt\\\"]}; echo \\${_vtsim_opts[\\\"vtsim vt compare\\\"]}\"");
  CHECK(vtsim::test::contains(vt.out, "compare"));
  CHECK(vtsim::test::contains(vt.out, "--policies"));
  // Completing a word: `vtsim repl<TAB>` -> replay; `vtsim replay --sum<TAB>` -> --summary.
  const auto words = conv_sh("bash -c \". " + script +
                             "; COMP_WORDS=(vtsim repl); COMP_CWORD=1; _vtsim; echo \\${COMPREPLY[@]}; "
                             "COMP_WORDS=(vtsim replay --sum); COMP_CWORD=2; _vtsim; echo \\${COMPREPLY[@]}\"");
  CHECK(words.out == "replay\n--summary\n");
}

TEST_CASE("cli: errors start with 'vtsim: error:' and name the flag typed, not an internal field") {
  const auto parse = conv_sh("$V replay --no-such-flag");
  CHECK(parse.code == 2);
  CHECK(parse.err.rfind("vtsim: error: ", 0) == 0);
  CHECK(vtsim::test::contains(parse.err, "vtsim replay --help"));
  const auto gen = conv_sh("$V trace gen walk --duration -1 -o -");
  CHECK(gen.code == 2);
  CHECK(vtsim::test::contains(gen.err, "vtsim: error: --duration: -1 is not in [0, 1e6] s"));
  const auto radius = conv_sh("$V trace gen orbit --radius -5 -o -");
  CHECK(radius.code == 2);
  CHECK(vtsim::test::contains(radius.err, "vtsim: error: --radius: "));
}

TEST_CASE("cli: store gen refuses parameters no replay accepts, before writing anything") {
  const std::string out = conv_tmp("tile7.vts");
  std::filesystem::remove(out);
  const auto tile = conv_sh("$V store gen -o " + out + " --size 4096x4096 --tile 7");
  CHECK(tile.code == 2);
  CHECK(vtsim::test::contains(tile.err, "vtsim: error: --tile: 7 is out of range [8, 65536] (no replay could read this store)"));
  CHECK_FALSE(std::filesystem::exists(out));
  const auto levels = conv_sh("$V store gen -o " + out + " --size 1024x1024 --levels 2");
  CHECK(levels.code == 2);
  CHECK(vtsim::test::contains(levels.err, "vtsim: error: --levels: 2 levels is fewer than any streaming system samples"));
  CHECK_FALSE(std::filesystem::exists(out));
  const auto dir = conv_sh("$V store gen -o /nonexistent_vtsim_dir/s.vts --size 1024x1024");
  CHECK(dir.code == 2);
  CHECK(vtsim::test::contains(dir.err, "vtsim: error: --output: "));
}

TEST_CASE("cli: a hint names a real config key and value (the town that does not fit)") {
  const auto r = conv_sh("$V replay --system vt --trace $SRC/tests/data/town_walk.csv --set scene.kind=town "
                         "--set texture.width=1024 --set texture.height=1024 --set texture.texels_per_m=4");
  CHECK(r.code == 2);
  CHECK(vtsim::test::contains(r.err, "vtsim: error: texture.texels_per_m: 4 texels/m puts the town's 1232 m ground on 4928 "
                                     "texels a side, more than the 1024x1024-texel texture: lower texture.texels_per_m below 0.83"));
  CHECK(vtsim::test::contains(r.err, "texture.texels_per_m=4 fits a 16384x16384 texture"));
  // The ground fits, the faces do not: the same keys named.
  const auto faces = conv_sh("$V replay --system vt --trace $SRC/tests/data/town_walk.csv --set scene.kind=town "
                             "--set texture.width=1024 --set texture.height=1024 --set texture.texels_per_m=0.5");
  CHECK(faces.code == 2);
  CHECK(vtsim::test::contains(faces.err, "vtsim: error: texture.texels_per_m: 0.5 texels/m packs the town's faces into more "
                                         "than the 1024x1024-texel texture: lower texture.texels_per_m or use a larger texture"));
}

TEST_CASE("cli: vt compare finds its standard traces beside the executable, whatever the working directory") {
  const auto r = conv_sh("cd / && $V vt compare --policies none --set run.fps=1 --json -q");
  CHECK(r.code == 0);
  CHECK(vtsim::test::contains(r.out, "\"trace\": \"walk\""));
  CHECK(vtsim::test::contains(r.out, "\"trace\": \"static\""));
}

TEST_CASE("cli: --json prints the results as JSON on stdout in every command that has it, --json-file writes them") {
  const std::string acc = conv_tmp("acc.txt");
  {
    std::ofstream f(acc);
    f << "1\n2\n1\n3\n1\n";
  }
  const auto mrc = conv_sh("$V mrc --accesses " + acc + " --sizes 3 --json");
  CHECK(mrc.code == 0);
  CHECK(mrc.out.rfind("{", 0) == 0);
  CHECK(vtsim::test::contains(mrc.out, "\"curve\""));
  CHECK_FALSE(vtsim::test::contains(mrc.out, "LRU miss-ratio curve, exact"));  // no table mixed in
  const auto mrc_stdin = conv_sh("$V mrc --accesses - --sizes 3 --json-file - < " + acc);
  CHECK(mrc_stdin.code == 0);
  CHECK(vtsim::test::contains(mrc_stdin.out, "\"curve\""));
  for (const std::string cmd : {"$V store info $SRC/tests/data/none.vts --json", "$V trace info $SRC/traces/walk.csv --json"}) {
    const auto r = conv_sh(cmd);
    CHECK((r.code == 2 || r.out.rfind("{", 0) == 0));
  }
}

TEST_CASE("cli: store gen and store verify --json, and a truncated store fails calibrate before any measurement") {
  const std::string store = conv_tmp("conv.vts"), cut = conv_tmp("conv_cut.vts");
  const auto gen = conv_sh("$V store gen -o " + store + " --size 1024x1024 --json");
  REQUIRE(gen.code == 0);
  CHECK(vtsim::test::contains(gen.out, "\"tiles\": "));
  const auto ok = conv_sh("$V store verify " + store + " --buffered --json");
  CHECK(ok.code == 0);
  CHECK(vtsim::test::contains(ok.out, "\"bad\": 0"));
  std::filesystem::copy_file(store, cut, std::filesystem::copy_options::overwrite_existing);
  std::filesystem::resize_file(cut, std::filesystem::file_size(store) / 2);
  const auto cal = conv_sh("$V calibrate --store " + cut + " --quick -q");
  CHECK(cal.code == 2);
  CHECK(vtsim::test::contains(cal.err, "vtsim: error: " + cut + ": truncated: the file has"));
  CHECK(cal.out.empty());
}

TEST_CASE("cli: a scene's missing file is named by the flag (view --obj) or the config key (replay scene.file)") {
  const auto view = conv_sh("$V view --scene mesh");
  CHECK(view.code == 2);
  CHECK(vtsim::test::contains(view.err, "vtsim: error: --obj: the mesh scene needs"));
  const auto replay = conv_sh("$V replay --trace $SRC/traces/static.csv --set scene.kind=mesh");
  CHECK(replay.code == 2);
  CHECK(vtsim::test::contains(replay.err, "vtsim: error: "));
  CHECK(vtsim::test::contains(replay.err, "scene.file"));
}

TEST_CASE("cli: --config - reads the config from stdin (errors name '-'), and view --json prints its results as JSON") {
  const auto cfg = conv_sh("printf \"upload.tiles_per_frame = 4\\n\" | $V replay --trace $SRC/traces/static.csv --set run.fps=2 --config - --json");
  REQUIRE(cfg.code == 0);
  const nlohmann::json s = nlohmann::json::parse(cfg.out);
  CHECK(s["config"]["upload.tiles_per_frame"] == 4);
  const auto bad = conv_sh("printf \"upload.no_such_key = 4\\n\" | $V replay --trace $SRC/traces/static.csv --config -");
  CHECK(bad.code == 2);
  CHECK(vtsim::test::contains(bad.err, "vtsim: error: -:1"));
  const auto both = conv_sh("$V replay --trace - --config - < $SRC/traces/static.csv");
  CHECK(both.code == 2);
  CHECK(vtsim::test::contains(both.err, "vtsim: error: --config: --config - and --trace - cannot both read stdin"));
  const auto view = conv_sh("$V view --size 64x36 --json -o " + conv_tmp("view.png"));
  REQUIRE(view.code == 0);
  const nlohmann::json v = nlohmann::json::parse(view.out);
  CHECK(v["buffer"]["size"][0] == 8);
  CHECK(v["tiles"]["touched"].get<std::size_t>() > 0);
  CHECK(v["levels"].size() > 0);
}

TEST_CASE("cli: --config is repeatable, files read in order, a later file's keys overriding, stdin once") {
  const std::string a = conv_tmp("a.toml"), b = conv_tmp("b.toml");
  std::ofstream(a) << "[upload]\ntiles_per_frame = 3\n[view]\ndivisor = 16\n";
  std::ofstream(b) << "[upload]\ntiles_per_frame = 7\n";
  const auto ab = conv_sh("$V replay -c " + a + " -c " + b + " --print-config");
  CHECK(ab.code == 0);
  CHECK(vtsim::test::contains(ab.out, "upload.tiles_per_frame = 7 "));
  CHECK(vtsim::test::contains(ab.out, "view.divisor = 16 "));  // a key only the first file sets stays
  const auto ba = conv_sh("$V replay -c " + b + " -c " + a + " --print-config");
  CHECK(vtsim::test::contains(ba.out, "upload.tiles_per_frame = 3 "));
  // One of them from stdin; an error in it names "-" and its line.
  const auto dash = conv_sh("$V replay -c - -c " + b + " --print-config < " + a);
  CHECK(dash.code == 0);
  CHECK(vtsim::test::contains(dash.out, "view.divisor = 16 "));
  const auto bad = conv_sh("printf \"[upload]\\ntiles_per_frame = x\\n\" | $V replay -c " + a + " -c - --print-config");
  CHECK(bad.code == 2);
  CHECK(vtsim::test::contains(bad.err, "vtsim: error: -:2: "));
  const auto twice = conv_sh("$V replay -c - -c - --print-config < " + a);
  CHECK(twice.code == 2);
  CHECK(vtsim::test::contains(twice.err, "--config: - (stdin) given twice"));
  // One value per --config: a second path without the flag is not taken as a config.
  const auto two = conv_sh("$V replay -c " + a + " " + b + " --print-config");
  CHECK(two.code != 0);
}
