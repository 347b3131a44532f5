#include "stream/exec/upload_fit.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace vtsim {

UploadFit fit_upload_model(const std::vector<UploadSample>& samples) {
  if (samples.empty()) throw std::invalid_argument("fit_upload_model: no samples");
  for (const UploadSample& s : samples)
    if (s.tiles < 1 || !std::isfinite(s.us) || s.us < 0.0)
      throw std::invalid_argument(fmt::format("fit_upload_model: bad sample ({} bytes, {} tiles, {} us)", s.bytes, s.tiles, s.us));
  // y = a + b x over (x = bytes, y = us per page), centred sums (exact for exact data).
  const auto n = static_cast<double>(samples.size());
  double mx = 0, my = 0;
  for (const UploadSample& s : samples) {
    mx += static_cast<double>(s.bytes);
    my += s.us / s.tiles;
  }
  mx /= n;
  my /= n;
  double sxx = 0, sxy = 0;
  for (const UploadSample& s : samples) {
    const double dx = static_cast<double>(s.bytes) - mx;
    sxx += dx * dx;
    sxy += dx * (s.us / s.tiles - my);
  }
  UploadFit f;
  double a = 0, b = 0;
  const auto through_origin = [&] {
    double xx = 0, xy = 0;
    for (const UploadSample& s : samples) {
      const auto x = static_cast<double>(s.bytes);
      xx += x * x;
      xy += x * (s.us / s.tiles);
    }
    return xx > 0 ? xy / xx : 0.0;
  };
  if (sxx <= 0) {
    b = through_origin();
    f.notes.push_back("one page size: the per-page and per-byte costs cannot be told apart; all of it counted per byte");
  } else {
    b = sxy / sxx;
    a = my - b * mx;
    if (b < 0) {
      f.notes.push_back(fmt::format("negative per-byte cost ({:.3g} us/byte) clamped to 0: per-page cost only", b));
      b = 0;
      a = my;
    } else if (a < 0) {
      f.notes.push_back(fmt::format("negative per-page cost ({:.3g} us) clamped to 0: per-byte cost refitted through the origin", a));
      a = 0;
      b = through_origin();
    }
  }
  f.per_tile_us = a;
  f.MBps = b > 0 ? 1.0 / b : 0.0;
  for (const UploadSample& s : samples) {
    const double m = s.tiles * (a + b * static_cast<double>(s.bytes));
    f.model_us.push_back(m);
    const double r = s.us > 0 ? (m - s.us) / s.us : 0.0;
    f.rel_residual.push_back(r);
    f.max_abs_rel = std::max(f.max_abs_rel, std::abs(r));
  }
  return f;
}

std::string upload_profile_toml(const UploadFit& fit, const std::vector<UploadSample>& samples, const std::string& source) {
  std::string t = fmt::format("# GPU upload (vtsim gl calibrate-upload): {}\n", source);
  t += "# model: a frame's copies take tiles x (per_tile_us + page bytes / link_MBps); least squares per page\n";
  t += "# page bytes, pages a frame, measured us a frame (median), model us, residual\n";
  for (std::size_t i = 0; i < samples.size(); ++i)
    t += fmt::format("# {:9} {:4} {:12.1f} {:12.1f} {:+7.1f} %\n", samples[i].bytes, samples[i].tiles, samples[i].us, fit.model_us[i],
                     fit.rel_residual[i] * 100.0);
  t += fmt::format("# largest |residual| {:.1f} %\n", fit.max_abs_rel * 100.0);
  for (const std::string& n : fit.notes) t += "# note: " + n + "\n";
  t += "[upload]\n";
  t += fmt::format("per_tile_us = {:.4f}    # fixed cost of a page's copy, fitted\n", fit.per_tile_us);
  t += fmt::format("link_MBps = {:.4f}    # per-byte cost of the copy, fitted{}\n", fit.MBps, fit.MBps > 0 ? "" : " (0: none measured)");
  return t;
}

}  // namespace vtsim
