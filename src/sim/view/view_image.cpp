#include "sim/view/view_image.h"

#include <vector>

#include "core/error.h"
#include "core/image_io.h"

namespace vtsim {

std::array<unsigned char, 3> level_colour(int level) {
  static constexpr unsigned char kPalette[12][3] = {
      {230, 25, 75}, {245, 130, 48}, {255, 225, 25},  {210, 245, 60},  {60, 180, 75},  {70, 240, 240},
      {0, 130, 200}, {145, 30, 180}, {240, 50, 230},  {250, 190, 212}, {170, 110, 40}, {255, 255, 255}};
  const auto& c = kPalette[(level % 12 + 12) % 12];
  return {c[0], c[1], c[2]};
}

void write_level_image(const std::string& path, const ViewBuffer& vb, int num_levels, int zoom) {
  if (zoom < 1 || zoom > 64) throw InputError("zoom", "must be in [1, 64]");
  if (vb.width < 1 || vb.height < 1) throw InputError(path, "empty feedback buffer");
  const int w = vb.width * zoom, h = vb.height * zoom;
  const std::size_t npix = static_cast<std::size_t>(vb.width) * static_cast<std::size_t>(vb.height);
  std::vector<unsigned char> img(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3, 0);
  for (const ViewSample& s : vb.samples) {
    if (s.pixel >= npix) throw InputError(path, "sample pixel index outside the buffer");
    const auto col = level_colour(desired_level(s.lod, num_levels));
    const int bx = static_cast<int>(s.pixel % static_cast<std::uint32_t>(vb.width));
    const int by = static_cast<int>(s.pixel / static_cast<std::uint32_t>(vb.width));
    for (int y = by * zoom; y < (by + 1) * zoom; ++y)
      for (int x = bx * zoom; x < (bx + 1) * zoom; ++x) {
        unsigned char* p = &img[(static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)) * 3];
        p[0] = col[0];
        p[1] = col[1];
        p[2] = col[2];
      }
  }
  const auto r = image_io::write_file(path, w, h, 3, image_io::PixelType::u8, img.data(), /*unassociated_alpha=*/false);
  if (r.status == image_io::WriteStatus::cannot_create)
    throw InputError(path, "cannot write an image of this type: " + r.error);
  if (r.status == image_io::WriteStatus::failed) throw InputError(path, "cannot write: " + r.error);
}

}  // namespace vtsim
