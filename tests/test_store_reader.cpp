#include <doctest/doctest.h>

#include <sys/stat.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "core/error.h"
#include "store_test_util.h"
#include "test_util.h"
#include "trace_test_util.h"
#include "stream/store/store_builder.h"
#include "stream/store/tile_store.h"

using namespace vtsim;
using namespace vtsim::store;
using vtsim::test::contains;

namespace {

// A small two-layer store: 300 x 200, tile 64, border 4 (zstd RGB + raw grey).
std::string make_store(const test::TempDir& dir, const std::string& name = "s.vts") {
  StoreSpec spec;
  spec.width = 300;
  spec.height = 200;
  spec.tile = 64;
  spec.border = 4;
  spec.layers = {{"albedo", 3, {CodecId::zstd, 3}, Transfer::srgb}, {"mask", 1, {CodecId::raw, 0}, Transfer::linear}};
  const std::string path = dir.file(name);
  StoreWriter w(path, spec);
  const Geometry& g = w.geometry();
  const Image8 img3 = test::make_image(300, 200, 3), img1 = test::make_image(300, 200, 1);
  const auto l3 = build_mip_chain(img3, Transfer::srgb, g.levels), l1 = build_mip_chain(img1, Transfer::linear, g.levels);
  for (std::uint32_t l = 0; l < g.levels; ++l)
    for (std::uint64_t y = 0; y < g.rows[l]; ++y)
      for (std::uint64_t x = 0; x < g.cols[l]; ++x)
        for (std::uint32_t layer = 0; layer < 2; ++layer) {
          std::vector<std::uint8_t> t(w.tile_bytes(layer));
          extract_tile(layer == 0 ? l3[l] : l1[l], g.tile, g.border, x, y, t.data());
          w.add_tile(TileKey(layer, l, std::int64_t(x), std::int64_t(y)), t.data());
        }
  w.commit();
  return path;
}

// Opens `path` expecting an InputError; returns its message ("" if it opened).
std::string open_error(const std::string& path) {
  try {
    TileStore::open(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// Rewrites the header checksum after a deliberate edit, so the check under test is reached.
void fix_header_checksum(std::vector<std::uint8_t>& b) {
  const std::uint32_t n = load_u32(&b[hdr::header_bytes]);
  store_u64(&b[hdr::header_checksum], 0);
  store_u64(&b[hdr::header_checksum], checksum64(b.data(), n));
}
void fix_index_checksum(std::vector<std::uint8_t>& b) {
  const std::uint64_t off = load_u64(&b[hdr::index_offset]), n = load_u64(&b[hdr::index_bytes]);
  store_u64(&b[hdr::index_checksum], checksum64(b.data() + off, n));
  fix_header_checksum(b);
}

}  // namespace

TEST_CASE("every record offset and read size is 4 KiB-aligned, records do not overlap, O_DIRECT reads work") {
  test::TempDir dir;
  const std::string path = make_store(dir);
  const TileStore s = TileStore::open(path);
  const auto file_size = std::filesystem::file_size(path);
  CHECK(file_size % 4096 == 0);
  CHECK(s.header().file_bytes == file_size);
  std::vector<std::pair<std::uint64_t, std::uint64_t>> spans;
  const auto& g = s.geometry();
  for (std::uint64_t slot = 0; slot < g.tile_count(); ++slot) {
    const TileKey k = g.key_of_slot(slot);
    CHECK(g.slot(k) == slot);
    const TileLocation loc = s.locate(k);
    CHECK(loc.offset % 4096 == 0);
    CHECK(loc.read_bytes % 4096 == 0);
    CHECK(loc.read_bytes >= loc.stored_bytes);
    CHECK(loc.read_bytes < loc.stored_bytes + 4096);
    CHECK(loc.offset + loc.read_bytes <= file_size);
    CHECK(s.stored_bytes(k) == loc.stored_bytes);
    spans.emplace_back(loc.offset, loc.offset + loc.read_bytes);
  }
  std::sort(spans.begin(), spans.end());
  for (std::size_t i = 1; i < spans.size(); ++i) CHECK(spans[i].first >= spans[i - 1].second);
  // The raw layer stores exactly the decoded size; the zstd layer less.
  const auto totals = s.totals();
  CHECK(totals[1].stored_bytes == totals[1].decoded_bytes);
  CHECK(totals[0].stored_bytes < totals[0].decoded_bytes);

  DirectOpen f = open_for_read(path, true);
  CHECK(f.file.direct() == f.warning.empty());
  MESSAGE("O_DIRECT on the test directory: " << (f.file.direct() ? "yes" : f.warning));
  AlignedBuffer rec, out(s.tile_bytes(0)), via_pread(s.tile_bytes(0));
  CHECK(reinterpret_cast<std::uintptr_t>(out.data()) % 4096 == 0);
  for (std::uint64_t slot = 0; slot < g.tile_count(); ++slot) {
    const TileKey k = g.key_of_slot(slot);
    const TileLocation loc = s.locate(k);
    rec.reserve(loc.read_bytes);
    CHECK(reinterpret_cast<std::uintptr_t>(rec.data()) % 4096 == 0);
    REQUIRE(f.file.pread_full(rec.data(), loc.read_bytes, loc.offset) == loc.read_bytes);
    s.verify_and_decode(k, rec.data(), loc.read_bytes, out.data(), out.size());
    s.read_tile(k, rec, via_pread.data(), via_pread.size());
    CHECK(std::equal(out.data(), out.data() + loc.decoded_bytes, via_pread.data()));
  }
}

TEST_CASE("a flipped byte in a record is a checksum error naming the tile, verify reports it") {
  test::TempDir dir;
  const std::string path = make_store(dir);
  const TileKey k(0, 1, 2, 1);
  std::uint64_t offset = 0;
  {
    const TileStore s = TileStore::open(path);
    offset = s.locate(k).offset;
    CHECK(test::run_vtsim("store verify " + path, "/dev/null") == 0);
  }
  auto b = test::read_bytes(path);
  b[offset + 17] ^= 0x40;
  test::write_bytes(path, b);
  const TileStore s = TileStore::open(path);  // the index is intact: open succeeds
  AlignedBuffer scratch;
  std::vector<std::uint8_t> out(s.tile_bytes(0));
  try {
    s.read_tile(k, scratch, out.data(), out.size());
    FAIL("no error");
  } catch (const InputError& e) {
    CHECK(contains(e.what(), "layer 0 level 1 tile (2, 1)"));
    CHECK(contains(e.what(), "checksum"));
    CHECK(contains(e.what(), path));
  }
  s.read_tile(TileKey(0, 1, 1, 1), scratch, out.data(), out.size());  // neighbours still read
  CHECK(test::run_vtsim("store verify " + path, "/dev/null") == 1);
  std::string listing;
  {
    FILE* p = ::popen((std::string(VTSIM_CLI) + " store verify " + path + " 2>/dev/null").c_str(), "r");
    REQUIRE(p);
    char buf[512];
    while (std::fgets(buf, sizeof buf, p)) listing += buf;
    ::pclose(p);
  }
  CHECK(contains(listing, "BAD " + path + ": layer 0 level 1 tile (2, 1)"));
  CHECK(contains(listing, "1 of " + std::to_string(s.index().size()) + " tiles are bad"));
}

TEST_CASE("corrupt stores are rejected at open with the field named") {
  test::TempDir dir;
  const std::string good = make_store(dir, "good.vts");
  const auto orig = test::read_bytes(good);
  const std::string bad = dir.file("bad.vts");
  int cli_checks = 3;  // the CLI's exit code for the first few cases (each run costs a process start)
  auto expect = [&](std::vector<std::uint8_t> bytes, const std::string& part) {
    test::write_bytes(bad, bytes);
    const std::string msg = open_error(bad);
    CAPTURE(msg);
    CHECK(contains(msg, bad));
    CHECK(contains(msg, part));
    if (cli_checks-- > 0) CHECK(test::run_vtsim("store info " + bad, "/dev/null") == 2);
  };
  CHECK(open_error(good).empty());

  auto b = orig;
  b[0] = 'X';
  expect(b, "field 'magic'");

  b = orig;
  store_u32(&b[hdr::version_major], 2);
  expect(b, "field 'version_major'");

  expect(std::vector<std::uint8_t>(orig.begin(), orig.begin() + 100), "truncated");
  expect(std::vector<std::uint8_t>(orig.begin(), orig.begin() + std::ptrdiff_t(orig.size() / 2)), "truncated");
  expect({}, "truncated");

  b = orig;
  b[hdr::width] ^= 1;  // no checksum fix
  expect(b, "field 'header_checksum'");

  b = orig;
  store_u64(&b[hdr::index_offset], orig.size() + 4096);
  fix_header_checksum(b);
  expect(b, "field 'index_offset'");

  b = orig;
  store_u64(&b[hdr::index_offset], 4096 + 17);
  fix_header_checksum(b);
  expect(b, "field 'index_offset'");

  b = orig;
  store_u64(&b[hdr::index_bytes], load_u64(&b[hdr::index_bytes]) + 32);
  fix_header_checksum(b);
  expect(b, "field 'index_bytes'");

  b = orig;
  store_u32(&b[hdr::tile_size], 0);
  fix_header_checksum(b);
  expect(b, "field 'tile_size'");

  b = orig;
  store_u32(&b[hdr::level_count], 40);
  fix_header_checksum(b);
  expect(b, "field 'level_count'");

  b = orig;
  store_u32(&b[kFixedHeaderBytes + lay::channels], 7);
  fix_header_checksum(b);
  expect(b, "layer 0 field 'channels'");

  // A layer name is printed by `store info` and written into its JSON: UTF-8, no control bytes.
  b = orig;
  b[kFixedHeaderBytes + lay::name] = 0xFF;
  fix_header_checksum(b);
  expect(b, "layer 0 field 'name': byte 0 of the name is not UTF-8");
  b = orig;
  b[kFixedHeaderBytes + lay::name + 1] = 0x1B;  // ESC: a terminal escape
  fix_header_checksum(b);
  expect(b, "layer 0 field 'name': byte 1 of the name is a control character");
  // A character cut short at the end, as builders before the check cut a default name at byte 31,
  // is dropped, with a warning naming the field: such stores still open, and nothing is lost silently.
  b = orig;
  {
    const std::uint8_t name[] = {'a', 'b', 0xE3, 0x81, 0};
    std::memcpy(&b[kFixedHeaderBytes + lay::name], name, sizeof name);
  }
  fix_header_checksum(b);
  test::write_bytes(bad, b);
  CHECK(open_error(bad).empty());
  CHECK(TileStore::open(bad).layer(0).name == "ab");
  REQUIRE(TileStore::open(bad).header().warnings.size() == 1);
  CHECK(TileStore::open(bad).header().warnings[0] ==
        bad + ": layer 0 field 'name': 2 trailing byte(s) of a character cut by the builder dropped (read as 'ab')");
  test::write_bytes(bad, orig);
  CHECK(TileStore::open(bad).header().warnings.empty());

  b = orig;
  b.resize(b.size() + 4096, 0);  // trailing bytes
  expect(b, "field 'file_bytes'");

  const std::uint64_t index = load_u64(&orig[hdr::index_offset]);
  b = orig;
  b[index + 3] ^= 1;  // index damaged, checksum not fixed
  expect(b, "field 'index_checksum'");

  b = orig;
  store_u64(&b[index + ent::offset], load_u64(&b[index + ent::offset]) + 512);  // misaligned record
  fix_index_checksum(b);
  expect(b, "index entry 0 (layer 0 level 0 tile (0, 0)) field 'offset'");

  b = orig;
  store_u64(&b[index + ent::offset], orig.size());  // record past the end
  fix_index_checksum(b);
  expect(b, "outside the data region");

  b = orig;
  store_u64(&b[index + kIndexEntryBytes + ent::offset], load_u64(&b[index + ent::offset]));  // two tiles, one place
  fix_index_checksum(b);
  expect(b, "overlaps");

  b = orig;
  store_u32(&b[index + ent::stored_bytes], 0);
  fix_index_checksum(b);
  expect(b, "field 'stored_bytes'");

  b = orig;
  store_u32(&b[index + ent::decoded_bytes], 5);
  fix_index_checksum(b);
  expect(b, "field 'decoded_bytes'");

  b = orig;
  store_u32(&b[index + ent::codec], 4);  // jpeg in a zstd layer
  fix_index_checksum(b);
  expect(b, "field 'codec'");

  CHECK(contains(open_error(dir.file("nope.vts")), "cannot open"));
}

TEST_CASE("lookups outside the texture and short buffers are errors, not crashes") {
  test::TempDir dir;
  const TileStore s = TileStore::open(make_store(dir));
  CHECK_FALSE(s.contains(TileKey(2, 0, 0, 0)));
  CHECK(s.level_count() == 10);  // 300 -> 150 -> 75 -> 38 -> 19 -> 10 -> 5 -> 3 -> 2 -> 1
  CHECK_FALSE(s.contains(TileKey(0, 10, 0, 0)));
  CHECK_FALSE(s.contains(TileKey(0, 0, 5, 0)));  // 300 / 64 -> 5 columns: 0..4
  CHECK(s.contains(TileKey(0, 0, 4, 3)));
  CHECK(s.stored_bytes(TileKey(0, 0, 5, 0)) == 0);
  CHECK_THROWS_AS(s.locate(TileKey(0, 0, 5, 0)), InputError);
  AlignedBuffer scratch;
  std::vector<std::uint8_t> small(10);
  CHECK_THROWS_AS(s.read_tile(TileKey(0, 0, 0, 0), scratch, small.data(), small.size()), InputError);
  const TileLocation loc = s.locate(TileKey(0, 0, 0, 0));
  std::vector<std::uint8_t> out(loc.decoded_bytes), rec(loc.stored_bytes - 1);
  CHECK_THROWS_AS(s.verify_and_decode(TileKey(0, 0, 0, 0), rec.data(), rec.size(), out.data(), out.size()), InputError);
}

TEST_CASE("the writer refuses missing and duplicate tiles and leaves nothing behind") {
  test::TempDir dir;
  StoreSpec spec;
  spec.width = 10;
  spec.height = 10;
  spec.tile = 8;
  spec.border = 0;
  spec.levels = 1;
  spec.layers = {{"a", 1, {CodecId::raw, 0}, Transfer::linear}};
  const std::string out = dir.file("w.vts");
  {
    StoreWriter w(out, spec);
    std::vector<std::uint8_t> t(w.tile_bytes(0), 1);
    w.add_tile(TileKey(0, 0, 0, 0), t.data());
    CHECK_THROWS_AS(w.add_tile(TileKey(0, 0, 0, 0), t.data()), InputError);
    CHECK_THROWS_AS(w.add_tile(TileKey(0, 0, 2, 0), t.data()), InputError);
    CHECK_THROWS_AS(w.commit(), InputError);  // 3 of 4 tiles missing
  }
  CHECK_FALSE(std::filesystem::exists(out));
  CHECK(std::filesystem::is_empty(dir.path));
}

TEST_CASE("stores are written only over regular files: FIFOs, directories and devices are never read or replaced") {
  test::TempDir dir;
  StoreSpec spec;
  spec.width = spec.height = 8;
  spec.tile = 8;
  spec.levels = 1;
  spec.layers = {{"a", 1, {CodecId::raw, 0}, Transfer::linear}};
  const std::string fifo = dir.file("fifo"), sub = dir.file("sub");
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  std::filesystem::create_directory(sub);
  // The store is renamed into place at commit: it must not replace a FIFO (or /dev/null as root).
  for (const std::string& out : {fifo, sub}) {
    CAPTURE(out);
    const std::string e = test::input_error([&] { StoreWriter w(out, spec); });
    CHECK(contains(e, out + ": exists and is not a regular file"));
  }
  CHECK(std::filesystem::is_fifo(fifo));
  // Opening a FIFO to read would block until a writer comes: refused before the open.
  CHECK(contains(test::input_error([&] { TileStore::open(fifo); }), fifo + ": not a regular file"));
  CHECK(contains(test::input_error([&] { TileStore::open(sub); }), sub + ": is a directory"));
  CHECK(contains(test::input_error([&] { TileStore::open("/dev/zero"); }), "/dev/zero: not a regular file"));
  // An index beyond 2^27 tiles is refused before it is allocated, naming --size.
  spec.width = std::uint64_t{1} << 34;
  spec.height = 1;
  spec.tile = 128;
  spec.levels = 0;
  CHECK(contains(test::input_error([&] { StoreWriter w(dir.file("big.vts"), spec); }), "--size"));
}

TEST_CASE("incompressible tiles are stored raw, and still decode") {
  test::TempDir dir;
  StoreSpec spec;
  spec.width = 16;
  spec.height = 16;
  spec.tile = 16;
  spec.border = 0;
  spec.levels = 1;
  spec.layers = {{"noise", 4, {CodecId::zstd, 19}, Transfer::linear}};
  const std::string out = dir.file("n.vts");
  std::vector<std::uint8_t> t(16 * 16 * 4);
  for (std::size_t i = 0; i < t.size(); ++i) t[i] = std::uint8_t(mix64(i) >> 7);
  {
    StoreWriter w(out, spec);
    w.add_tile(TileKey(0, 0, 0, 0), t.data());
    w.commit();
  }
  const TileStore s = TileStore::open(out);
  CHECK(s.index()[0].codec == CodecId::raw);
  CHECK(s.index()[0].stored_bytes == t.size());
  AlignedBuffer scratch;
  std::vector<std::uint8_t> back(t.size());
  s.read_tile(TileKey(0, 0, 0, 0), scratch, back.data(), back.size());
  CHECK(back == t);
}
