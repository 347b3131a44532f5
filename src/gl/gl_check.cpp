#include "gl/gl_check.h"

namespace vtsim::gl {

PerPixel per_pixel(const ViewBuffer& vb, int levels, int tile_size) {
  PerPixel p;
  const auto n = static_cast<std::size_t>(vb.width) * static_cast<std::size_t>(vb.height);
  p.level.assign(n, -1);
  p.tx.assign(n, 0);
  p.ty.assign(n, 0);
  for (const ViewSample& s : vb.samples) {
    const int l = desired_level(s.lod, levels);
    p.level[s.pixel] = l;
    p.tx[s.pixel] = (s.u >> l) / tile_size;
    p.ty[s.pixel] = (s.v >> l) / tile_size;
    p.tiles.insert({l, p.tx[s.pixel], p.ty[s.pixel]});
  }
  return p;
}

PerPixel per_pixel(const FeedbackFrame& f, int levels, int tile_size) {
  PerPixel p;
  p.level.assign(f.px.size(), -1);
  p.tx.assign(f.px.size(), 0);
  p.ty.assign(f.px.size(), 0);
  for (std::size_t i = 0; i < f.px.size(); ++i) {
    const FeedbackTexel& t = f.px[i];
    if (t.status != 1) continue;
    const int l = desired_level(t.lod, levels);
    p.level[i] = l;
    p.tx[i] = static_cast<std::int64_t>(t.u >> l) / tile_size;
    p.ty[i] = static_cast<std::int64_t>(t.v >> l) / tile_size;
    p.tiles.insert({l, p.tx[i], p.ty[i]});
  }
  return p;
}

Agreement agree(const PerPixel& a, const PerPixel& b) {
  Agreement r;
  for (std::size_t i = 0; i < a.level.size() && i < b.level.size(); ++i) {
    if (a.level[i] < 0 && b.level[i] < 0) continue;
    ++r.either;
    if (a.level[i] == b.level[i] && a.tx[i] == b.tx[i] && a.ty[i] == b.ty[i]) ++r.same;
    else if (a.level[i] >= 0 && b.level[i] >= 0 && a.level[i] != b.level[i]) ++r.level_off;
  }
  std::size_t inter = 0;
  for (const auto& t : a.tiles) inter += b.tiles.count(t);
  const std::size_t uni = a.tiles.size() + b.tiles.size() - inter;
  r.jaccard = uni == 0 ? 1.0 : static_cast<double>(inter) / static_cast<double>(uni);
  return r;
}

}  // namespace vtsim::gl
