#include "core/view.h"

namespace vtsim {

int mip_level_count(TextureExtent e) {
  std::int64_t m = e.width > e.height ? e.width : e.height;
  int n = 1;
  while (m > 1) {
    m = (m + 1) / 2;
    ++n;
  }
  return n;
}

}  // namespace vtsim
