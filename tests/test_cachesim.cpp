// vtsim cachesim (docs/cache.md, "Cache simulation on access files"): libCacheSim's trace formats
// (oracleGeneral, CSV with named columns), the capacity lists, exact misses per policy and bound
// on hand-checked sequences, a miss-for-miss cross-check against small independent Python
// references (tests/data/cachesim_reference.py), and the CLI's exit codes.
#include <doctest/doctest.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <unistd.h>

#include "cache/policy/access_formats.h"
#include "cache/policy/access_io.h"
#include "cache/policy/cachesim.h"
#include "core/error.h"
#include "test_util.h"

using namespace vtsim;

namespace {

std::string cs_tmp(const std::string& name) {
  const auto d = std::filesystem::temp_directory_path() / ("vtsim_cachesim_" + std::to_string(getpid()));
  std::filesystem::create_directories(d);
  return (d / name).string();
}

void cs_write(const std::string& path, const std::string& bytes) {
  FILE* f = std::fopen(path.c_str(), "wb");
  REQUIRE(f != nullptr);
  if (!bytes.empty()) REQUIRE(std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size());
  std::fclose(f);
}

// The InputError message of f(), or "" if it did not throw one.
template <class F>
std::string cs_error(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

void cs_le(std::string& out, std::uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
}

std::vector<Access> cs_keys(const std::vector<std::uint64_t>& keys) {
  std::vector<Access> out;
  for (std::uint64_t k : keys) out.push_back(Access{k, 1});
  return out;
}

// The whole of a file (C stdio: the iostream readers trip GCC 12's -Wnull-dereference in unity
// batches).
std::string cs_read(const std::string& path) {
  std::string out;
  if (FILE* f = std::fopen(path.c_str(), "rb")) {
    char buf[4096];
    std::size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) out.append(buf, n);
    std::fclose(f);
  }
  return out;
}

vtsim::test::CliRun cs_cli(const std::string& args) {
  return vtsim::test::run_vtsim_capture(args, cs_tmp("err.txt"));
}

}  // namespace

TEST_CASE("cachesim: oracleGeneral records are 24 packed little-endian bytes (libCacheSim's oracleGeneralBin.h)") {
  // clock_time 7, obj_id 0x0102030405060708, obj_size 4096, next_access_vtime 1; then obj 9,
  // size 0 (skipped, as libCacheSim's reader does by default); then obj_id 0x0102030405060708 again.
  std::string b;
  cs_le(b, 7, 4), cs_le(b, 0x0102030405060708ull, 8), cs_le(b, 4096, 4), cs_le(b, 2, 8);
  cs_le(b, 8, 4), cs_le(b, 9, 8), cs_le(b, 0, 4), cs_le(b, ~0ull, 8);
  cs_le(b, 9, 4), cs_le(b, 0x0102030405060708ull, 8), cs_le(b, 512, 4), cs_le(b, ~0ull, 8);
  REQUIRE(b.size() == 72);
  const OracleGeneralRead r = parse_oracle_general(b, "t.bin");
  REQUIRE(r.log.accesses.size() == 2);
  CHECK(r.log.accesses[0].key == 0x0102030405060708ull);
  CHECK(r.log.accesses[0].size == 4096);
  CHECK(r.log.accesses[1].size == 512);
  CHECK(r.zero_size_skipped == 1);
  // The writer's records read back; next_access_vtime is the next index, -1 for none.
  AccessLog log;
  log.accesses = {{5, 100}, {6, 200}, {5, 100}};
  const std::string w = format_oracle_general(log);
  REQUIRE(w.size() == 72);
  CHECK(static_cast<unsigned char>(w[16]) == 2);  // record 0's next access: index 2
  CHECK(w.substr(64, 8) == std::string(8, '\xff'));  // record 2's: -1
  const OracleGeneralRead back = parse_oracle_general(w, "w.bin");
  REQUIRE(back.log.accesses.size() == 3);
  CHECK(back.log.accesses[1].key == 6);
  CHECK(back.log.accesses[1].size == 200);
}

TEST_CASE("cachesim: a bad oracleGeneral file is refused with file:record") {
  std::string b;
  cs_le(b, 1, 4), cs_le(b, 5, 8), cs_le(b, 10, 4), cs_le(b, 0, 8);
  CHECK(cs_error([&] { parse_oracle_general(b.substr(0, 23), "t.bin"); }).find("t.bin:1: truncated: the file's 23 bytes end 23 bytes into this record") == 0);
  CHECK(cs_error([&] { parse_oracle_general(b + b.substr(0, 5), "t.bin"); }).find("t.bin:2: truncated") == 0);
  CHECK(cs_error([&] { parse_oracle_general("", "t.bin"); }) == "t.bin: is empty: an oracleGeneral trace holds 24-byte records");
  std::string reserved = b;
  cs_le(reserved, 1, 4), cs_le(reserved, ~0ull, 8), cs_le(reserved, 10, 4), cs_le(reserved, 0, 8);
  CHECK(cs_error([&] { parse_oracle_general(reserved, "t.bin"); }).find("t.bin:2: obj_id 0xffffffffffffffff is reserved") == 0);
  std::string zero;
  cs_le(zero, 1, 4), cs_le(zero, 5, 8), cs_le(zero, 0, 4), cs_le(zero, 0, 8);
  CHECK(cs_error([&] { parse_oracle_general(zero, "t.bin"); }) == "t.bin: holds no request: all 1 records have obj_size 0");
  // Through the file reader: an empty file on disk.
  const std::string empty = cs_tmp("empty.oracleGeneral.bin");
  cs_write(empty, "");
  CHECK(cs_error([&] { read_oracle_general(empty); }).find("is empty") != std::string::npos);
}

TEST_CASE("cachesim: CSV traces with libCacheSim's column options, by number or header name") {
  // The first lines of libCacheSim's data/trace.csv (cloudPhysics, version,time,op,size,lbn).
  const std::string text =
      "version,time,op,size,lbn\n1,33898,2a,512,42932745\n1,33898,2a,6656,40409911\r\n\n1,33899,2a,4096,42932745\n";
  CsvAccessOptions o;
  o.obj_id_col = "lbn", o.obj_size_col = "size", o.time_col = "time", o.has_header = true;
  AccessLog log = parse_access_csv(text, "t.csv", o);
  REQUIRE(log.accesses.size() == 3);
  CHECK(log.accesses[0].key == 42932745);
  CHECK(log.accesses[0].size == 512);
  CHECK(log.accesses[1].size == 6656);
  CHECK(log.accesses[2].key == 42932745);
  // The same by 1-based numbers (libCacheSim's obj-id-col=5, obj-size-col=4, time-col=2).
  CsvAccessOptions n;
  n.obj_id_col = "5", n.obj_size_col = "4", n.time_col = "2", n.has_header = true;
  AccessLog byn = parse_access_csv(text, "t.csv", n);
  REQUIRE(byn.accesses.size() == 3);
  CHECK(byn.accesses[1].key == 40409911);
  // No size column: every request weighs 1. Another delimiter, quotes, text ids hashed.
  CsvAccessOptions t;
  t.obj_id_col = "2", t.delimiter = ';', t.obj_id_is_num = false;
  AccessLog txt = parse_access_csv("1;\"a;b\"\n2;c\n3;\"a;b\"\n", "t.csv", t);
  REQUIRE(txt.accesses.size() == 3);
  CHECK(txt.accesses[0].key == txt.accesses[2].key);
  CHECK(txt.accesses[0].key != txt.accesses[1].key);
  CHECK(txt.accesses[0].size == 1);
}

TEST_CASE("cachesim: a bad CSV trace is refused naming the line and the field or column") {
  CsvAccessOptions o;
  o.obj_id_col = "lbnx", o.obj_size_col = "size", o.has_header = true;
  const std::string text = "version,time,op,size,lbn\n1,33898,2a,512,42932745\n";
  CHECK(cs_error([&] { parse_access_csv(text, "t.csv", o); }) ==
        "t.csv: obj-id-col 'lbnx' is not a column of the header (columns: version, time, op, size, lbn)");
  o.obj_id_col = "lbn";
  CHECK(cs_error([&] { parse_access_csv(text + "1,2,2a,0,5\n", "t.csv", o); }) ==
        "t.csv:3: obj-size '0' is not a decimal integer in [1, 2^40]");
  CHECK(cs_error([&] { parse_access_csv(text + "1,2,2a,5\n", "t.csv", o); }) == "t.csv:3: 4 fields, but obj-id-col is column 5");
  CHECK(cs_error([&] { parse_access_csv(text + "1,2,2a,5,x7\n", "t.csv", o); }).find("t.csv:3: obj-id 'x7' is not a decimal") == 0);
  CHECK(cs_error([&] { parse_access_csv(text + "1,2,2a,5,\"7\n", "t.csv", o); }) == "t.csv:3: field 5: a quote opened and never closed");
  CHECK(cs_error([&] { parse_access_csv("", "t.csv", o); }) == "t.csv: is empty: a CSV trace holds one request per line");
  CHECK(cs_error([&] { parse_access_csv("version,time,op,size,lbn\n", "t.csv", o); }) == "t.csv: holds a header and no request");
  CsvAccessOptions noh;
  noh.obj_id_col = "lbn";
  CHECK(cs_error([&] { parse_access_csv("1,2\n", "t.csv", noh); }).find("obj-id-col 'lbn': a column name needs a header") != std::string::npos);
  CsvAccessOptions time;
  time.obj_id_col = "1", time.time_col = "2";
  CHECK(cs_error([&] { parse_access_csv("1,nan\n", "t.csv", time); }) == "t.csv:1: time 'nan' is not a finite number");
}

TEST_CASE("cachesim: capacity lists: bytes with units, object counts, fractions, and bad items named") {
  CapacityList l = parse_capacity_list("128MiB, 256MiB,1GiB,0.5GiB,1GB,4096B,2KiB", "--sizes");
  CHECK(l.unit == CapacityUnit::kBytes);
  CHECK(l.unit_given);
  const std::vector<std::uint64_t> want = {128ull << 20, 256ull << 20, 1ull << 30, 512ull << 20, 1000000000ull, 4096, 2048};
  REQUIRE(l.items.size() == want.size());
  for (std::size_t i = 0; i < want.size(); ++i) CHECK(l.items[i].value == want[i]);
  CHECK(l.items[1].token == "256MiB");
  CapacityList c = parse_capacity_list("1000,2000", "--sizes");
  CHECK(c.unit == CapacityUnit::kObjects);
  CHECK(c.items[1].value == 2000);
  CapacityList f = parse_capacity_list("0.1,0.5,1000", "--sizes");
  CHECK(f.unit == CapacityUnit::kObjects);
  resolve_capacities(f, 50, "--sizes");
  CHECK(f.items[0].value == 5);
  CHECK(f.items[1].value == 25);
  CHECK_FALSE(parse_capacity_list("0.25", "--sizes").unit_given);
  CHECK(cs_error([] { parse_capacity_list("128MiB,12XB", "--sizes"); }) ==
        "--sizes: '12XB': unknown unit 'XB' (B, KiB, MiB, GiB, TiB, KB, MB, GB, TB; none: an object count)");
  CHECK(cs_error([] { parse_capacity_list("1MiB,100", "--sizes"); }) == "--sizes: '1MiB' is bytes and '100' an object count: give one kind");
  CHECK(cs_error([] { parse_capacity_list("1,,2", "--sizes"); }).find("an empty item") != std::string::npos);
  CHECK(cs_error([] { parse_capacity_list("", "--sizes"); }).find("no capacity given") != std::string::npos);
  CHECK(cs_error([] { parse_capacity_list("0", "--sizes"); }).find("'0': an object count is an integer in [1, 2^62]") != std::string::npos);
  CHECK(cs_error([] { parse_capacity_list("1.5", "--sizes"); }).find("'1.5': a fraction of the footprint is in (0, 1]") != std::string::npos);
  CHECK(cs_error([] { parse_capacity_list("MiB", "--sizes"); }).find("does not start with a number") != std::string::npos);
  CHECK(cs_error([] { parse_capacity_list("99999999TiB", "--sizes"); }).find("outside [1 B, 2^62 B]") != std::string::npos);
  CapacityList tiny = parse_capacity_list("0.001", "--sizes");
  CHECK(cs_error([&] { resolve_capacities(tiny, 10, "--sizes"); }).find("rounds to 0") != std::string::npos);
}

TEST_CASE("cachesim: exact misses on the textbook string, 3 frames, for every policy and bound") {
  // Silberschatz et al.'s reference string (the counts are derived in tests/test_cache_policy.cpp):
  // FIFO 15, LRU 12, CLOCK 11, S3-FIFO 15, ARC 13, OPT 9. belady_reused (libCacheSim's Belady:
  // a key never requested again is not admitted) 8: the 7 at request 17 stays out, so 0 and 1
  // both stay and hit at the end. level_lru reads frames: every access here is one frame.
  const auto seq = cs_keys({7, 0, 1, 2, 0, 3, 0, 4, 2, 3, 0, 3, 2, 1, 2, 0, 1, 7, 0, 1});
  const std::map<std::string, std::uint64_t> want = {{"fifo", 15}, {"lru", 12}, {"clock", 11}, {"s3fifo", 15},
                                                     {"arc", 13},  {"belady", 9}, {"belady_reused", 8}};
  for (const auto& [p, m] : want) {
    const auto& p_ = p;  // clang 14 cannot capture a structured binding (CAPTURE's lambda)
    CAPTURE(p_);
    const CacheSimResult r = cachesim_run(seq, p, 3, CapacityUnit::kObjects);
    CHECK(r.stats.requests == 20);
    CHECK(r.stats.misses == m);
  }
  CHECK(cachesim_run(seq, "pfoo_lower", 3, CapacityUnit::kObjects).stats.misses <= 8);
  CHECK(cs_error([&] { cachesim_run(seq, "lfu", 3, CapacityUnit::kObjects); }).find("unknown policy 'lfu'") != std::string::npos);
}

TEST_CASE("cachesim: exact misses and miss bytes with sizes, derived by hand") {
  // Capacity 10 bytes; a(6) b(3) a(6) c(5) b(3) a(6); 29 bytes requested.
  // LRU: a, b miss; a hits; c needs 5: evicts b then a; b misses (c, b); a misses, evicts c.
  //      5 misses, 6+3+5+3+6 = 23 bytes. CLOCK: a's hit sets its bit; c: a goes round, b leaves,
  //      then a leaves; the same 5 misses, 23 bytes.
  // FIFO: c evicts a (oldest) only: b, c = 8 bytes; b hits; a misses, evicting b and c: 4, 20.
  // Belady (Belady-Size): c evicts a (next use 5, furthest of a and b); b hits; a misses and
  //      evicts c (never again): 4 misses, 20 bytes.
  // belady_reused: c is never requested again, so it is not admitted; b and a hit: 3, 14.
  const std::vector<Access> seq = {{1, 6}, {2, 3}, {1, 6}, {3, 5}, {2, 3}, {1, 6}};
  const std::map<std::string, std::pair<std::uint64_t, std::uint64_t>> want = {
      {"lru", {5, 23}}, {"clock", {5, 23}}, {"fifo", {4, 20}}, {"belady", {4, 20}}, {"belady_reused", {3, 14}}};
  for (const auto& [p, m] : want) {
    const auto& p_ = p;  // clang 14 cannot capture a structured binding (CAPTURE's lambda)
    CAPTURE(p_);
    const CacheSimResult r = cachesim_run(seq, p, 10, CapacityUnit::kBytes);
    CHECK(r.stats.misses == m.first);
    CHECK(r.stats.bytes_missed == m.second);
    CHECK(r.bytes_requested == 29);
  }
  // An object larger than the cache is not admitted (a miss each time; libCacheSim's
  // cache_can_insert_default refuses it alike) and evicts nothing.
  const std::vector<Access> big = {{1, 4}, {2, 20}, {1, 4}, {2, 20}};
  const CacheSimResult r = cachesim_run(big, "lru", 10, CapacityUnit::kBytes);
  CHECK(r.stats.misses == 3);
  CHECK(r.stats.rejected == 2);
  CHECK(r.stats.bytes_missed == 44);
  // Object counts: the same sequence at 2 objects. LRU: c evicts b, b evicts a, a evicts c: 5.
  // FIFO: c evicts a; b hits; a evicts b: 4.
  CHECK(cachesim_run(seq, "lru", 2, CapacityUnit::kObjects).stats.misses == 5);
  CHECK(cachesim_run(seq, "fifo", 2, CapacityUnit::kObjects).stats.misses == 4);
  CHECK(access_footprint(seq, CapacityUnit::kBytes) == 14);
  CHECK(access_footprint(seq, CapacityUnit::kObjects) == 3);
}

TEST_CASE("cachesim: LRU, FIFO, CLOCK and Belady equal independent Python references miss for miss") {
  // tests/data/cachesim_reference.py: a few lines each, from libCacheSim's semantics as read
  // (evict until the object fits, then insert; larger than the cache: not admitted).
  std::uint64_t state = 99;
  const auto rnd = [&] { return (state = state * 6364136223846793005ull + 1442695040888963407ull) >> 33; };
  for (int seq_i = 0; seq_i < 3; ++seq_i) {
    AccessLog log;
    for (int i = 0; i < 1500; ++i) {
      const std::uint64_t k = rnd() % 3 ? rnd() % 60 : 60 + rnd() % 400;  // a hot set and a cold tail
      log.accesses.push_back(Access{k, 1 + (k * 2654435761u) % 64});     // a key keeps its size
    }
    const std::string path = cs_tmp("ref_" + std::to_string(seq_i) + ".txt");
    write_access_file(path, log);
    for (const auto& [unit, caps] : {std::pair<std::string, std::vector<std::uint64_t>>{"objects", {1, 7, 40, 200}},
                                     {"bytes", {50, 300, 1500, 6000}}}) {
      std::string caps_arg;
      for (std::uint64_t c : caps) caps_arg += (caps_arg.empty() ? "" : ",") + std::to_string(c);
      const auto run = vtsim::test::run_capture("python3 " + std::string(VTSIM_SOURCE_DIR) + "/tests/data/cachesim_reference.py " +
                                                    path + " " + unit + " " + caps_arg + " lru,fifo,clock,belady,belady_reused 2>" +
                                                    cs_tmp("py_err.txt"),
                                                cs_tmp("py_err.txt"));
      REQUIRE_MESSAGE(run.code == 0, run.err);
      int lines = 0;
      std::size_t at = 0;
      while (at < run.out.size()) {
        const std::size_t nl = run.out.find('\n', at);
        const std::string line = run.out.substr(at, nl == std::string::npos ? std::string::npos : nl - at);
        at = nl == std::string::npos ? run.out.size() : nl + 1;
        char name[64] = {};
        unsigned long long cap = 0, requests = 0, misses = 0, miss_bytes = 0;
        if (std::sscanf(line.c_str(), "%63s %llu %llu %llu %llu", name, &cap, &requests, &misses, &miss_bytes) != 5) continue;
        const std::string policy = name;
        CAPTURE(seq_i);
        const auto& unit_ = unit;  // clang 14 cannot capture a structured binding (CAPTURE's lambda)
        CAPTURE(unit_);
        CAPTURE(policy);
        CAPTURE(cap);
        const CacheSimResult r =
            cachesim_run(log.accesses, policy, cap, unit == "bytes" ? CapacityUnit::kBytes : CapacityUnit::kObjects);
        CHECK(r.stats.requests == requests);
        CHECK(r.stats.misses == misses);
        // Belady-Size breaks ties among keys never requested again by key, the reference by
        // insertion: with sizes the bytes may differ there, the count of misses too in principle.
        if (unit == "objects" || policy.rfind("belady", 0) != 0) CHECK(r.stats.bytes_missed == miss_bytes);
        ++lines;
      }
      CHECK(lines == 5 * 4);
    }
  }
}

TEST_CASE("cachesim: the CLI prints the table, writes CSV and JSON, and refuses bad input with exit 2") {
  AccessLog log;
  log.accesses = {{1, 6}, {2, 3}, {1, 6}, {3, 5}, {2, 3}, {1, 6}};
  const std::string acc = cs_tmp("acc.txt");
  write_access_file(acc, log);
  auto r = cs_cli("cachesim -a " + acc + " -s 10B -p lru,fifo,belady_reused");
  CHECK(r.code == 0);
  CHECK(vtsim::test::contains(r.out, "6 requests, 3 objects, footprint"));
  CHECK(vtsim::test::contains(r.out, "lru                            10            6            5   0.833333               23   0.793103"));
  const std::string csv = cs_tmp("out.csv"), json = cs_tmp("out.json");
  r = cs_cli("cachesim -a " + acc + " -s 10B,2KiB -p lru,fifo -o " + csv);
  CHECK(r.code == 0);
  const std::string csv_text = cs_read(csv);
  CHECK(csv_text.rfind("policy,capacity_bytes,requests,misses,miss_ratio,bytes_requested,miss_bytes,byte_miss_ratio\n"
                       "lru,10,6,5,0.8333333333333334,29,23,0.7931034482758621\n", 0) == 0);
  r = cs_cli("cachesim -a " + acc + " -s 2 -p fifo -o " + json);
  CHECK(r.code == 0);
  const std::string json_text = cs_read(json);
  CHECK(vtsim::test::contains(json_text, "\"unit\": \"objects\""));
  CHECK(vtsim::test::contains(json_text, "\"misses\": 4"));
  // oracleGeneral in, by its name.
  const std::string og = cs_tmp("t.oracleGeneral.bin");
  cs_write(og, format_oracle_general(log));
  r = cs_cli("cachesim -a " + og + " -s 10B -p belady --json");
  CHECK(r.code == 0);
  CHECK(vtsim::test::contains(r.out, "\"format\": \"oracleGeneral\""));
  CHECK(vtsim::test::contains(r.out, "\"miss_bytes\": 20"));
  // CSV in, columns by name.
  const std::string cv = cs_tmp("t.csv");
  cs_write(cv, "id,bytes\n1,6\n2,3\n1,6\n3,5\n2,3\n1,6\n");
  r = cs_cli("cachesim -a " + cv + " --has-header --obj-id-col id --obj-size-col bytes -s 10B -p lru");
  CHECK(r.code == 0);
  CHECK(vtsim::test::contains(r.out, "lru                            10            6            5"));
  // Bad input: exit 2, "vtsim: error:" naming the flag, item, file:record or column.
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"cachesim -a " + acc + " -s 10XB", "vtsim: error: --sizes: '10XB': unknown unit 'XB'"},
      {"cachesim -a " + acc + " -s 10B -p lru,lfu", "vtsim: error: --policies: unknown policy 'lfu'"},
      {"cachesim -a " + acc + " -s 10B -o out.txt", "vtsim: error: -o: 'out.txt': the format is the extension"},
      {"cachesim -a " + acc + " -s 10B --obj-id-col 1", "vtsim: error: --obj-id-col: reads CSV traces"},
      {"cachesim -a " + cv + " --has-header --obj-id-col idx -s 2", "obj-id-col 'idx' is not a column of the header (columns: id, bytes)"},
      {"cachesim -a " + cv + " --has-header --obj-id-col id -s 10B", "vtsim: error: --sizes: byte capacities, but the requests of"},
      {"cachesim -a " + og + ".missing -s 10B", "vtsim: error:"},
  };
  for (const auto& [args, msg] : bad) {
    const auto& args_ = args;  // clang 14 cannot capture a structured binding (CAPTURE's lambda)
    CAPTURE(args_);
    r = cs_cli(args);
    CHECK(r.code == 2);
    CHECK(vtsim::test::contains(r.err, msg));
    CHECK(r.out.empty());
  }
  const std::string trunc = cs_tmp("cut.oracleGeneral.bin");
  cs_write(trunc, format_oracle_general(log).substr(0, 30));
  r = cs_cli("cachesim -a " + trunc + " -s 10B");
  CHECK(r.code == 2);
  CHECK(vtsim::test::contains(r.err, "cut.oracleGeneral.bin:2: truncated"));
  const std::string empty = cs_tmp("empty.csv");
  cs_write(empty, "");
  r = cs_cli("cachesim -a " + empty + " --obj-id-col 1 -s 2");
  CHECK(r.code == 2);
  CHECK(vtsim::test::contains(r.err, "empty.csv: is empty"));
}
