// The image module boundary (core/image_io.h): files and in-memory images round-trip through the
// dlopen'ed module, and a module that cannot be loaded is a clear error, not a crash, and costs
// nothing to commands that touch no image.
#include <doctest/doctest.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "core/error.h"
#include "core/image_io.h"
#include "test_util.h"
#include "view_test_util.h"

using namespace vtsim;
using image_io::PixelType;
using test::contains;
using test::slurp;
using image_io::ReadStatus;
using image_io::WriteStatus;

namespace {

template <class T>
std::vector<T> round_trip(const std::string& path, int w, int h, int c, PixelType type, const std::vector<T>& px,
                          bool unassociated_alpha, image_io::ImageSpec& spec) {
  const auto wr = image_io::write_file(path, w, h, c, type, px.data(), unassociated_alpha);
  REQUIRE_MESSAGE(wr.status == WriteStatus::ok, wr.error);
  auto in = image_io::ImageReader::open_file(path, unassociated_alpha);
  REQUIRE_MESSAGE(in.ok(), in.error());
  spec = in.spec();
  std::vector<T> back(px.size());
  REQUIRE(in.read(c, type, back.data()) == ReadStatus::ok);
  std::remove(path.c_str());
  return back;
}

}  // namespace

TEST_CASE("image module: 8-bit, 16-bit and float images round-trip through files") {
  CHECK(contains(image_io::require_module(), "libvtsim_image.so"));
  image_io::ImageSpec spec;

  // RGBA with transparent texels that keep their colour: alpha stays unassociated.
  std::vector<std::uint8_t> rgba(5 * 3 * 4);
  for (std::size_t i = 0; i < rgba.size(); ++i) rgba[i] = static_cast<std::uint8_t>(i * 37 % 251);
  for (std::size_t p = 0; p < 15; p += 4) rgba[p * 4 + 3] = 0;
  CHECK(round_trip(test::temp_path("rgba.png"), 5, 3, 4, PixelType::u8, rgba, true, spec) == rgba);
  CHECK(spec.width == 5);
  CHECK(spec.height == 3);
  CHECK(spec.depth == 1);
  CHECK(spec.channels == 4);
  CHECK(spec.is_uint8);
  CHECK_FALSE(spec.is_float);

  std::vector<std::uint16_t> gray16(4 * 4);
  for (std::size_t i = 0; i < gray16.size(); ++i) gray16[i] = static_cast<std::uint16_t>(i * 4099);
  CHECK(round_trip(test::temp_path("gray16.png"), 4, 4, 1, PixelType::u16, gray16, false, spec) == gray16);
  CHECK_FALSE(spec.is_uint8);
  CHECK_FALSE(spec.is_float);

  const std::vector<float> rgbf = {0.0f, 0.25f, 1.5f, -2.0f, 1e-3f, 3.0f};
  CHECK(round_trip(test::temp_path("rgb.tif"), 2, 1, 3, PixelType::f32, rgbf, false, spec) == rgbf);
  CHECK(spec.channels == 3);
  CHECK(spec.is_float);
}

TEST_CASE("image module: in-memory PNG round-trips, and failures come back as messages") {
  std::vector<std::uint8_t> px(6 * 2 * 3);
  for (std::size_t i = 0; i < px.size(); ++i) px[i] = static_cast<std::uint8_t>(i * 11);
  std::vector<std::uint8_t> bytes;
  std::string error;
  REQUIRE(image_io::encode_memory("png", px.data(), 6, 2, 3, {{"png:compressionLevel", 9}}, bytes, error));
  CHECK(error.empty());
  {
    auto in = image_io::ImageReader::open_memory("png", bytes.data(), bytes.size());
    REQUIRE(in.ok());
    CHECK(in.spec().width == 6);
    CHECK(in.spec().channels == 3);
    std::vector<std::uint8_t> back(px.size());
    CHECK(in.read(3, PixelType::u8, back.data(), 1) == ReadStatus::ok);
    CHECK(back == px);
  }
  const std::vector<std::uint8_t> junk = {1, 2, 3, 4, 5};
  CHECK_FALSE(image_io::ImageReader::open_memory("png", junk.data(), junk.size()).ok());
  CHECK_FALSE(image_io::encode_memory("nosuchformat", px.data(), 6, 2, 3, {}, bytes, error));
  CHECK_FALSE(error.empty());

  const auto missing = image_io::ImageReader::open_file("/nonexistent/dir/x.png", false);
  CHECK_FALSE(missing.ok());
  CHECK_FALSE(missing.error().empty());
  const auto wr = image_io::write_file(test::temp_path("x.nosuchformat"), 6, 2, 3, PixelType::u8, px.data(), false);
  CHECK(wr.status == WriteStatus::cannot_create);
  CHECK_FALSE(wr.error.empty());
  const auto wr2 = image_io::write_file("/nonexistent/dir/x.png", 6, 2, 3, PixelType::u8, px.data(), false);
  CHECK(wr2.status == WriteStatus::failed);
}

TEST_CASE("image module: a module that cannot be loaded is a clear error, and only where images are used") {
  const std::string log = test::temp_path("log.txt"), png = test::temp_path("x.png");
  const std::string cli = VTSIM_CLI;
  const std::string bad = "/nonexistent/dir/libvtsim_image.so";
  const std::string env = "VTSIM_IMAGE_MODULE=" + bad + " ";

  // Commands that read or write no image do not load the module.
  CHECK(test::run_shell(env + cli + " --version", log) == 0);
  CHECK(test::run_shell(env + cli + " capacity --size 32768 --clipsize 1024 --layers albedo:rgba8", log) == 0);

  // Writing an image needs it: exit 2 with the module path and the loader's reason.
  CHECK(test::run_shell(env + cli + " view --scene plane --pos 4096,4096,1.7 --size 64x36 -o " + png, log) == 2);
  const std::string out = slurp(log);
  CAPTURE(out);
  CHECK(contains(out, "vtsim: error: " + bad));
  CHECK(contains(out, "cannot load the image module"));
  CHECK(contains(out, "No such file or directory"));
  CHECK(contains(out, "VTSIM_IMAGE_MODULE"));

  // A file that is not a shared object.
  const std::string junk = test::temp_path("libjunk.so");
  std::ofstream(junk) << "not a shared object\n";
  CHECK(test::run_shell("VTSIM_IMAGE_MODULE=" + junk + " " + cli + " view --scene plane --pos 4096,4096,1.7 --size 64x36 -o " + png,
            log) == 2);
  CHECK(contains(slurp(log), "vtsim: error: " + junk + ": cannot load the image module"));

  std::remove(junk.c_str());
  std::remove(png.c_str());
  std::remove(log.c_str());
}

TEST_CASE("image module: read_chunked gives whole rows in order, whole rows of tiles for a tiled file") {
  const std::string dir = std::filesystem::temp_directory_path().string();
  // Scanlines: a 37 × 29 RGB PNG read in chunks of 5 rows (a chunk size of 5 rows' bytes).
  const int w = 37, h = 29, c = 3;
  std::vector<std::uint8_t> px(static_cast<std::size_t>(w * h * c));
  for (std::size_t i = 0; i < px.size(); ++i) px[i] = static_cast<std::uint8_t>(i * 31 + 7);
  const std::string png = dir + "/vtsim-chunked.png";
  REQUIRE(image_io::write_file(png, w, h, c, PixelType::u8, px.data(), true).status == WriteStatus::ok);
  auto in = image_io::ImageReader::open_file(png, true);
  REQUIRE(in.ok());
  std::vector<std::uint8_t> back;
  std::vector<std::pair<int, int>> chunks;
  CHECK(in.read_chunked<std::uint8_t>(c, 5 * w * c, image_io::OnDamage::stop, [&](int y0, int y1, const std::uint8_t* v) {
    chunks.emplace_back(y0, y1);
    back.insert(back.end(), v, v + (y1 - y0) * w * c);
  }) == ReadStatus::ok);
  CHECK(back == px);
  CHECK(chunks == std::vector<std::pair<int, int>>{{0, 5}, {5, 10}, {10, 15}, {15, 20}, {20, 25}, {25, 29}});
  std::remove(png.c_str());

  // Tiles: 40 × 70 grey in 16 × 16 tiles, asked for chunks of 20 rows: one row of tiles (16 rows) a
  // chunk, the last one partial; as float (v / 255, to OpenImageIO's rounding).
  const std::string tif = dir + "/vtsim-chunked.tif";
  test::write_tiled_tiff(tif, 40, 70, 16, 16);
  auto tin = image_io::ImageReader::open_file(tif, true);
  REQUIRE(tin.ok());
  CHECK(tin.spec().tile_width == 16);
  CHECK(tin.spec().tile_height == 16);
  chunks.clear();
  std::uint64_t bad = 0;
  CHECK(tin.read_chunked<float>(1, 20 * 40 * sizeof(float), image_io::OnDamage::stop, [&](int y0, int y1, const float* v) {
    chunks.emplace_back(y0, y1);
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < 40; ++x)
        bad += std::lround(v[(y - y0) * 40 + x] * 255.0f) != static_cast<std::uint8_t>(x * 7 + y * 13);
  }) == ReadStatus::ok);
  CHECK(bad == 0);
  CHECK(chunks == std::vector<std::pair<int, int>>{{0, 16}, {16, 32}, {32, 48}, {48, 64}, {64, 70}});
  std::remove(tif.c_str());
}

TEST_CASE("image module: the spec names the reader, and readers that decode the whole image are charged for it") {
  // The names image_io::whole_image_decode_bytes matches: a misspelt one would fall to the
  // conservative default and pass unnoticed, so each is read back from a file of its format.
  const std::string dir = std::filesystem::temp_directory_path().string();
  const int w = 64, h = 32, c = 3;  // OpenJPEG's default 6 resolution levels need 32 pixels a side
  std::vector<std::uint8_t> px(static_cast<std::size_t>(w * h * c), 100);
  const double pixels = w * h;
  const std::vector<std::tuple<const char*, const char*, double>> cases = {
      {"tif", "tiff", 0.0},           {"exr", "openexr", 0.0},       {"hdr", "hdr", 0.0},
      {"bmp", "bmp", 0.0},            {"sgi", "sgi", 0.0},           {"png", "png", pixels * c},
      {"pnm", "pnm", pixels * c},     {"tga", "targa", pixels * c},  {"jpg", "jpeg", pixels * c * 2},
      {"jp2", "jpeg2000", pixels * c * 4}, {"webp", "webp", pixels * 4}, {"gif", "gif", pixels * 4 * 8},
  };
  for (const auto& [ext_c, name, whole] : cases) {
    const std::string ext = ext_c;
    CAPTURE(ext);
    const std::string path = dir + "/vtsim-format." + ext;
    REQUIRE(image_io::write_file(path, w, h, c, PixelType::u8, px.data(), true).status == WriteStatus::ok);
    auto in = image_io::ImageReader::open_file(path, true);
    REQUIRE(in.ok());
    CHECK(in.spec().format == name);
    // For 8-bit files; the float ones (exr, hdr) have no whole-image term either.
    CHECK(image_io::whole_image_decode_bytes(in.spec()) == whole * (in.spec().is_uint8 ? 1.0 : 0.0));
    std::remove(path.c_str());
  }
}

TEST_CASE("image module: a JPEG whose Photoshop IPTC block overruns its APP13 segment is refused before OpenImageIO reads it") {
  // OpenImageIO 2.4 copies the IPTC block's declared size from the segment's buffer unchecked
  // (heap-buffer-overflow under ASan: tests/fuzz/corpus/image/asan_jpeg_app13_iptc_overrun.jpg).
  const std::string dir = std::filesystem::temp_directory_path().string();
  const std::string good = dir + "/vtsim-app13-good.jpg";
  std::vector<std::uint8_t> px(16 * 8 * 3, 90);
  REQUIRE(image_io::write_file(good, 16, 8, 3, PixelType::u8, px.data(), true).status == WriteStatus::ok);
  const std::string jpeg = slurp(good);
  REQUIRE(jpeg.size() > 2);
  // APP13 after SOI: "Photoshop 3.0\0", "8BIM", 0x0404, 4 skipped bytes, the IPTC size, the block
  // (one IIM record: 1C 02, tag 5 "ObjectName", 2-byte length 3, "abc").
  auto with_app13 = [&](int declared, const std::string& block) {
    std::string seg = std::string("Photoshop 3.0") + '\0' + "8BIM" + "\x04\x04" + std::string(4, '\0') +
                      static_cast<char>(declared >> 8) + static_cast<char>(declared & 0xFF) + block;
    const std::size_t length = seg.size() + 2;
    return jpeg.substr(0, 2) + "\xFF\xED" + static_cast<char>(length >> 8) + static_cast<char>(length & 0xFF) + seg +
           jpeg.substr(2);
  };
  const std::string record = std::string("\x1C\x02\x05\x00\x03", 5) + "abc";
  auto open = [&](const std::string& bytes) {
    const std::string path = dir + "/vtsim-app13.jpg";
    std::ofstream(path, std::ios::binary) << bytes;
    auto in = image_io::ImageReader::open_file(path, true);
    std::remove(path.c_str());
    return in;
  };
  {  // the block as declared: opens, and decodes
    auto in = open(with_app13(static_cast<int>(record.size()), record));
    REQUIRE(in.ok());
    std::vector<std::uint8_t> back(px.size());
    CHECK(in.read(3, PixelType::u8, back.data()) == ReadStatus::ok);
  }
  {  // declaring 200 bytes where 8 follow
    auto in = open(with_app13(200, record));
    CHECK_FALSE(in.ok());
    CHECK(contains(in.error(), "JPEG APP13 segment at byte 2: its IPTC block declares 200 bytes, more than the 8"));
  }
  {  // behind bytes libjpeg skips to find the marker (stray bytes, FF fill, a stuffed FF 00)
    const std::string bad = with_app13(200, record);
    auto in = open(bad.substr(0, 2) + std::string("junk\xFF\x00\xFF\xFF", 8) + bad.substr(2));
    CHECK_FALSE(in.ok());
    CHECK(contains(in.error(), "JPEG APP13 segment at byte 10: its IPTC block declares 200 bytes"));
  }
  {  // cut inside the header OpenImageIO reads
    const std::string cut = jpeg.substr(0, 2) + std::string("\xFF\xED\x00\x10Photoshop 3.0\0", 18) + jpeg.substr(2);
    auto in = open(cut);
    CHECK_FALSE(in.ok());
    CHECK(contains(in.error(), "holds 14 bytes, too few for the Photoshop IPTC header"));
  }
  {  // the same check in memory (the JPEG tile codec's payloads come from untrusted stores)
    const std::string bad = with_app13(200, record);
    auto mem = image_io::ImageReader::open_memory("jpg", reinterpret_cast<const std::uint8_t*>(bad.data()), bad.size());
    CHECK_FALSE(mem.ok());
    CHECK(contains(mem.error(), "its IPTC block declares 200 bytes"));
  }
  std::remove(good.c_str());
}

TEST_CASE("image module: an OpenEXR header attribute declaring more bytes than the file holds is refused before OpenEXR allocates it") {
  // OpenEXR 3.1 sizes a string attribute by its declared size before reading it: 1,466 bytes made
  // it allocate 2.1 GB (tests/fuzz/corpus/image/oom_exr_string_attribute_2gb.exr). Every header
  // of a multi-part file is walked: the last part's 'compression' attribute is made to lie.
  const std::string two_part = slurp(std::string(VTSIM_TEST_DATA) + "/two_part_16x8.exr");
  REQUIRE(two_part.size() > 100);
  const std::string dir = std::filesystem::temp_directory_path().string();
  const std::string path = dir + "/vtsim-exr-header.exr";
  std::ofstream(path, std::ios::binary) << two_part;
  {
    auto in = image_io::ImageReader::open_file(path, true);
    REQUIRE(in.ok());
    CHECK(in.spec().format == "openexr");
  }
  const std::string attr = std::string("compression") + '\0' + "compression" + '\0';
  const std::size_t second = two_part.rfind(attr);
  REQUIRE(second != std::string::npos);
  REQUIRE(second != two_part.find(attr));
  std::string lying = two_part;
  lying.replace(second + attr.size(), 4, std::string("\xFF\xFF\xFF\x7F", 4));
  std::ofstream(path, std::ios::binary | std::ios::trunc) << lying;
  auto in = image_io::ImageReader::open_file(path, true);
  CHECK_FALSE(in.ok());
  CHECK(contains(in.error(), "OpenEXR header attribute 'compression' (compression) at byte " + std::to_string(second) +
                                 " declares 2147483647 bytes, more than the"));
  std::remove(path.c_str());
}

TEST_CASE("image module: read_chunked stops at the first chunk the reader reports damaged, or reads on") {
  // A truncated JPEG: libjpeg warns "Premature end of JPEG file" and fills the missing rows grey,
  // and OpenImageIO returns the read as done with a pending error (ok_with_error).
  const std::string jpg = std::filesystem::temp_directory_path().string() + "/vtsim-cut.jpg";
  const int w = 64, h = 256;
  std::vector<std::uint8_t> px(static_cast<std::size_t>(w * h));
  for (std::size_t i = 0; i < px.size(); ++i) px[i] = static_cast<std::uint8_t>((i * 2654435761u) >> 13);
  REQUIRE(image_io::write_file(jpg, w, h, 1, PixelType::u8, px.data(), true).status == WriteStatus::ok);
  test::cut_file(jpg, 0.5);
  for (const auto on : {image_io::OnDamage::stop, image_io::OnDamage::read_on}) {
    CAPTURE(static_cast<int>(on));
    auto in = image_io::ImageReader::open_file(jpg, true);
    REQUIRE(in.ok());
    int rows = 0;
    CHECK(in.read_chunked<std::uint8_t>(1, 16 * w, on, [&](int y0, int y1, const std::uint8_t*) {
      CHECK(y0 == rows);
      rows = y1;
    }) == ReadStatus::ok_with_error);
    CHECK(contains(in.error(), "Premature end of JPEG file"));
    if (on == image_io::OnDamage::stop) {
      CHECK(rows > 0);  // the chunks before the damage
      CHECK(rows < h);
    } else {
      CHECK(rows == h);
    }
  }
  std::remove(jpg.c_str());
}

TEST_CASE("image module: a PNG chunk declaring more bytes than the file holds is refused before libpng allocates it") {
  const std::string dir = std::filesystem::temp_directory_path().string();
  const std::string good = dir + "/vtsim-png-good.png";
  std::vector<std::uint8_t> px(8 * 8 * 3, 77);
  REQUIRE(image_io::write_file(good, 8, 8, 3, PixelType::u8, px.data(), true).status == WriteStatus::ok);
  const std::string bytes = slurp(good);
  REQUIRE(bytes.size() > 33);
  CHECK(image_io::ImageReader::open_file(good, true).ok());
  // After the signature (8 bytes) and IHDR (25): a tEXt chunk declaring 1,560,281,159 bytes with
  // 5 bytes behind it (the fuzz finding declared the same; libpng cleared 1.6 GB in 9 s for it).
  std::string lying = bytes.substr(0, 33) + std::string("\x5d\x00\x00\x47", 4) + "tEXtabcde" + bytes.substr(33);
  const std::string bad = dir + "/vtsim-png-lying.png";
  std::ofstream(bad, std::ios::binary) << lying;
  const auto in = image_io::ImageReader::open_file(bad, true);
  CHECK_FALSE(in.ok());
  CHECK(contains(in.error(), "PNG chunk 'tEXt' at byte 33 declares 1560281159 bytes of data"));
  const auto mem = image_io::ImageReader::open_memory(
      "png", reinterpret_cast<const std::uint8_t*>(lying.data()), lying.size());
  CHECK_FALSE(mem.ok());
  CHECK(contains(mem.error(), "PNG chunk 'tEXt' at byte 33"));
  // Cut inside its last chunk (IEND's CRC): refused at open, naming the chunk.
  std::ofstream(bad, std::ios::binary | std::ios::trunc) << bytes.substr(0, bytes.size() - 2);
  const auto cut = image_io::ImageReader::open_file(bad, true);
  CHECK_FALSE(cut.ok());
  CHECK(contains(cut.error(), "PNG chunk 'IEND'"));
  std::remove(good.c_str());
  std::remove(bad.c_str());
}

namespace {
std::size_t thread_count() {  // this process's threads (/proc/self/task)
  std::size_t n = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator("/proc/self/task")) ++n;
  return n;
}
}  // namespace

// ctest runs each test case in its own process, so the module is loaded here for the first time.
// Without the join in image_io.cpp log4cplus (through libopenvdb) leaves 4 idle threads. A joined
// thread can stay listed in /proc/self/task for a moment after pthread_join returns (the kernel
// wakes the joiner before it releases the task; CI saw it on a loaded machine): the count is read
// until it is back, for up to 10 s; threads still running stay listed and fail the check.
TEST_CASE("image module: loading it leaves no library thread running (log4cplus's idle pool is joined)") {
  const std::size_t before = thread_count();
  CHECK(contains(image_io::require_module(), "libvtsim_image.so"));
  std::size_t after = thread_count();
  for (int ms = 0; ms < 10000 && after != before; ++ms) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    after = thread_count();
  }
  CHECK(after == before);
}

#if defined(__SANITIZE_ADDRESS__)
// cmake/sanitizer_options.cpp: every executable of the ASan build carries intercept_tls_get_addr=0,
// without which LeakSanitizer's tracer crashed at exit on CI now and then. ASan's help=1 prints each
// flag's current value.
TEST_CASE("sanitizer build: vtsim runs with intercept_tls_get_addr=0 whatever ASAN_OPTIONS says") {
  const std::string log = test::temp_path("asan_help.txt");
  CHECK(test::run_shell("ASAN_OPTIONS=help=1 " + std::string(VTSIM_CLI) + " --version", log) == 0);
  const std::string out = slurp(log);
  const auto at = out.find("\tintercept_tls_get_addr\n");
  REQUIRE(at != std::string::npos);
  CHECK(contains(out.substr(at, 120), "(Current Value: false)"));
  std::remove(log.c_str());
}
#endif
