#include <doctest/doctest.h>

#include <cmath>

#include "core/error.h"
#include "store_test_util.h"
#include "stream/store/i_codec.h"

using namespace vtsim;
using store::CodecId;

namespace {

double psnr(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b) {
  double se = 0;
  for (std::size_t i = 0; i < a.size(); ++i) se += (double(a[i]) - double(b[i])) * (double(a[i]) - double(b[i]));
  const double mse = se / double(a.size());
  return mse == 0 ? 1e9 : 10.0 * std::log10(255.0 * 255.0 / mse);
}

}  // namespace

TEST_CASE("lossless codecs round-trip every channel count exactly, including odd sizes") {
  for (CodecId id : {CodecId::raw, CodecId::zstd, CodecId::lz4, CodecId::png}) {
    const auto codec = make_codec(id, default_codec_param(id));
    CHECK(codec->lossless());
    for (std::uint32_t c = 1; c <= 4; ++c)
      for (auto [w, h] : {std::pair{136, 136}, std::pair{7, 5}, std::pair{1, 1}}) {
        CAPTURE(codec->name());
        CAPTURE(c);
        const int width = w;  // clang 14 cannot capture a structured binding (CAPTURE's lambda)
        CAPTURE(width);
        const Image8 img = test::make_image(std::uint64_t(w), std::uint64_t(h), c, 7);
        const auto bytes = codec->encode(img.texels.data(), w, h, int(c));
        std::vector<std::uint8_t> out(img.texels.size(), 0xAB);
        codec->decode(bytes.data(), bytes.size(), w, h, int(c), out.data());
        CHECK(out == img.texels);
      }
  }
}

TEST_CASE("zstd and lz4 levels are configurable and all decode to the same texels") {
  Image8 img = test::make_image(136, 136, 3, 3);
  for (std::size_t i = 0; i < img.texels.size(); ++i) img.texels[i] = std::uint8_t((i / 3 % 136 + i / 408) / 2);  // smooth
  for (auto [id, level] : {std::pair{CodecId::zstd, 1}, std::pair{CodecId::zstd, 19}, std::pair{CodecId::lz4, 0},
                           std::pair{CodecId::lz4, 9}}) {
    const auto bytes = make_codec(id, level)->encode(img.texels.data(), 136, 136, 3);
    CHECK(bytes.size() < img.texels.size());
    std::vector<std::uint8_t> out(img.texels.size());
    decoder_for(id).decode(bytes.data(), bytes.size(), 136, 136, 3, out.data());
    CHECK(out == img.texels);
  }
  CHECK(make_codec(CodecId::zstd, 19)->encode(img.texels.data(), 136, 136, 3).size() <
        make_codec(CodecId::zstd, 1)->encode(img.texels.data(), 136, 136, 3).size());
}

TEST_CASE("jpeg round-trips 1 and 3 channels within a PSNR bound and refuses 2 and 4") {
  const auto jpeg = make_codec(CodecId::jpeg, 90);
  CHECK_FALSE(jpeg->lossless());
  for (std::uint32_t c : {1u, 3u}) {
    CAPTURE(c);
    const Image8 img = test::make_image(136, 136, c, 5);
    const auto bytes = jpeg->encode(img.texels.data(), 136, 136, int(c));
    CHECK(bytes.size() < img.texels.size() / 2);
    std::vector<std::uint8_t> out(img.texels.size());
    jpeg->decode(bytes.data(), bytes.size(), 136, 136, int(c), out.data());
    CHECK(psnr(img.texels, out) > 30.0);
    CHECK(psnr(img.texels, out) < 1e9);  // it is lossy: not bit-exact on a noisy image
  }
  CHECK_FALSE(jpeg->supports_channels(2));
  CHECK_FALSE(jpeg->supports_channels(4));
  const Image8 rgba = test::make_image(8, 8, 4);
  CHECK_THROWS_AS(jpeg->encode(rgba.texels.data(), 8, 8, 4), CodecError);
}

TEST_CASE("corrupt or mismatched payloads throw CodecError, never crash") {
  const Image8 img = test::make_image(32, 32, 3, 11);
  for (CodecId id : {CodecId::raw, CodecId::zstd, CodecId::lz4, CodecId::png, CodecId::jpeg}) {
    const auto codec = make_codec(id, default_codec_param(id));
    CAPTURE(codec->name());
    auto bytes = codec->encode(img.texels.data(), 32, 32, 3);
    std::vector<std::uint8_t> out(32 * 33 * 3);
    // Expected size differs from what the payload holds.
    CHECK_THROWS_AS(codec->decode(bytes.data(), bytes.size(), 32, 33, 3, out.data()), CodecError);
    // Truncated to a few bytes.
    CHECK_THROWS_AS(codec->decode(bytes.data(), 5, 32, 32, 3, out.data()), CodecError);
    // Garbage.
    std::vector<std::uint8_t> junk(bytes.size());
    for (std::size_t i = 0; i < junk.size(); ++i) junk[i] = std::uint8_t(mix64(i) & 0xFF);
    if (id != CodecId::raw)  // raw cannot tell garbage from texels: the checksum's job
      CHECK_THROWS_AS(codec->decode(junk.data(), junk.size(), 32, 32, 3, out.data()), CodecError);
  }
  // A zstd frame whose content is valid but one byte short of the tile.
  std::vector<std::uint8_t> shorter(img.texels.begin(), img.texels.end() - 1);
  const auto z = make_codec(CodecId::zstd, 3)->encode(shorter.data(), int(shorter.size()), 1, 1);
  std::vector<std::uint8_t> out(img.texels.size());
  CHECK_THROWS_AS(decoder_for(CodecId::zstd).decode(z.data(), z.size(), 32, 32, 3, out.data()), CodecError);
  // lz4 of a shorter block decodes short: rejected.
  const auto l = make_codec(CodecId::lz4, 0)->encode(shorter.data(), int(shorter.size()), 1, 1);
  CHECK_THROWS_AS(decoder_for(CodecId::lz4).decode(l.data(), l.size(), 32, 32, 3, out.data()), CodecError);
}

TEST_CASE("codec specs parse names and parameters and reject bad ones naming the option") {
  CHECK(parse_codec_spec("zstd:5", "--codec").param == 5);
  CHECK(parse_codec_spec("zstd", "--codec").param == default_codec_param(CodecId::zstd));
  CHECK(parse_codec_spec("jpg:75", "--codec").id == CodecId::jpeg);
  CHECK(parse_codec_spec("lz4", "--codec").id == CodecId::lz4);
  for (const char* bad : {"zstd:99", "zstd:0", "lz4:2", "png:10", "jpeg:0", "jpeg:abc", "webp", "zstd:", "zstd:5x"}) {
    CAPTURE(bad);
    try {
      parse_codec_spec(bad, "--codec");
      FAIL("accepted");
    } catch (const InputError& e) {
      CHECK(e.where() == "--codec");
    }
  }
}
