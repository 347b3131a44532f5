#include "stream/produce/brush_images.h"

#include <fnmatch.h>

#include <algorithm>
#include <filesystem>

#include "core/error.h"
#include "stream/store/store_builder.h"

namespace vtsim::produce {

namespace {

bool is_pattern(const std::string& s) { return s.find_first_of("*?[") != std::string::npos; }

std::vector<std::string> expand_pattern(const std::string& pattern) {
  namespace fs = std::filesystem;
  const fs::path p(pattern);
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  const std::string name = p.filename().string();
  std::vector<std::string> out;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
    if (it->is_regular_file(ec) && fnmatch(name.c_str(), it->path().filename().c_str(), FNM_PERIOD) == 0)
      out.push_back(p.has_parent_path() ? (dir / it->path().filename()).string() : it->path().filename().string());
  if (out.empty()) throw InputError(pattern, "no brush image matches this pattern");
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

std::vector<std::string> expand_brush_files(const std::vector<std::string>& specs) {
  std::vector<std::string> files;
  for (const std::string& s : specs) {
    if (is_pattern(s) && !std::filesystem::exists(s)) {
      const auto m = expand_pattern(s);
      files.insert(files.end(), m.begin(), m.end());
    } else {
      files.push_back(s);
    }
  }
  return files;
}

Rgba8 read_brush(const std::string& path) {
  const Image8 im = read_image8(path, store::Transfer::linear);
  Rgba8 b;
  b.width = static_cast<int>(im.width);
  b.height = static_cast<int>(im.height);
  b.texels.resize(static_cast<std::size_t>(im.width) * static_cast<std::size_t>(im.height) * 4);
  for (std::size_t t = 0; t < b.texels.size() / 4; ++t) {
    const std::uint8_t* s = &im.texels[t * im.channels];
    std::uint8_t* d = &b.texels[t * 4];
    switch (im.channels) {  // grey, grey + alpha, RGB, RGBA
      case 1: d[0] = d[1] = d[2] = s[0], d[3] = 255; break;
      case 2: d[0] = d[1] = d[2] = s[0], d[3] = s[1]; break;
      case 3: d[0] = s[0], d[1] = s[1], d[2] = s[2], d[3] = 255; break;
      default: std::copy_n(s, 4, d);
    }
  }
  return b;
}

}  // namespace vtsim::produce
