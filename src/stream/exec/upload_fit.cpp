#include "stream/exec/upload_fit.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace vtsim {

namespace {

// Weighted least squares of y = us / tiles on the features in `mask` (bit 0: 1 -> a, bit 1: bytes
// -> b, bit 2: 1 / tiles -> c); false when singular. coef[i] is 0 for a feature left out.
bool solve_upload(const std::vector<UploadSample>& samples, unsigned mask, double coef[3]) {
  int idx[3], k = 0;
  for (int i = 0; i < 3; ++i)
    if (mask >> i & 1u) idx[k++] = i;
  double m[3][4] = {};
  for (const UploadSample& s : samples) {
    const double all[3] = {1.0, static_cast<double>(s.bytes) * 1e-6, 1.0 / s.tiles};  // bytes in MB: conditioning
    const double y = s.us / s.tiles;
    for (int i = 0; i < k; ++i) {
      for (int j = 0; j < k; ++j) m[i][j] += s.weight * all[idx[i]] * all[idx[j]];
      m[i][3] += s.weight * all[idx[i]] * y;
    }
  }
  double scale = 0;
  for (int i = 0; i < k; ++i) scale = std::max(scale, std::abs(m[i][i]));
  // Gauss-Jordan with partial pivoting.
  for (int col = 0; col < k; ++col) {
    int piv = col;
    for (int r = col + 1; r < k; ++r)
      if (std::abs(m[r][col]) > std::abs(m[piv][col])) piv = r;
    if (!(std::abs(m[piv][col]) > 1e-12 * scale)) return false;
    for (int j = 0; j < 4; ++j) std::swap(m[col][j], m[piv][j]);
    for (int r = 0; r < k; ++r) {
      if (r == col) continue;
      const double q = m[r][col] / m[col][col];
      for (int j = col; j < 4; ++j) m[r][j] -= q * m[col][j];
    }
  }
  coef[0] = coef[1] = coef[2] = 0.0;
  for (int i = 0; i < k; ++i) coef[idx[i]] = m[i][3] / m[i][i];
  coef[1] *= 1e-6;  // per MB -> per byte
  return true;
}

double weighted_sse(const std::vector<UploadSample>& samples, const double coef[3]) {
  double e = 0;
  for (const UploadSample& s : samples) {
    const double d = coef[0] + coef[1] * static_cast<double>(s.bytes) + coef[2] / s.tiles - s.us / s.tiles;
    e += s.weight * d * d;
  }
  return e;
}

}  // namespace

UploadFit fit_upload_model(const std::vector<UploadSample>& samples) {
  if (samples.empty()) throw std::invalid_argument("fit_upload_model: no samples");
  for (const UploadSample& s : samples)
    if (s.tiles < 1 || !std::isfinite(s.us) || s.us < 0.0 || !(s.weight > 0.0) || !std::isfinite(s.weight))
      throw std::invalid_argument(fmt::format("fit_upload_model: bad sample ({} bytes, {} tiles, {} us)", s.bytes, s.tiles, s.us));
  // Non-negative least squares by enumeration: of the fits on each subset of {a, b, c} whose
  // coefficients are all >= 0, the one with the least weighted squared error (the full model
  // when its coefficients are).
  UploadFit f;
  double best[3] = {0, 0, 0}, best_e = weighted_sse(samples, best);
  unsigned best_mask = 0;
  // Ties (a per-page and a per-frame cost are one term at a single batch size) keep the earlier:
  // the per-page cost first, the simulated clock's term.
  for (const unsigned mask : {7u, 3u, 5u, 1u, 6u, 2u, 4u}) {
    double coef[3];
    if (!solve_upload(samples, mask, coef) || coef[0] < 0 || coef[1] < 0 || coef[2] < 0) continue;
    const double e = weighted_sse(samples, coef);
    if (best_mask == 0 || e < best_e * (1 - 1e-12)) {
      std::copy(coef, coef + 3, best);
      best_e = e;
      best_mask = mask;
    }
  }
  const char* names[3] = {"per-page", "per-byte", "per-frame"};
  for (int i = 0; i < 3; ++i)
    if (!(best_mask >> i & 1u)) f.notes.push_back(fmt::format("no non-negative {} cost fits with the others: left at 0", names[i]));
  f.per_tile_us = best[0];
  f.MBps = best[1] > 0 ? 1.0 / best[1] : 0.0;
  f.per_frame_us = best[2];
  for (const UploadSample& s : samples) {
    const double m = best[2] + s.tiles * (best[0] + best[1] * static_cast<double>(s.bytes));
    f.model_us.push_back(m);
    const double r = s.us > 0 ? (m - s.us) / s.us : 0.0;
    f.rel_residual.push_back(r);
    f.max_abs_rel = std::max(f.max_abs_rel, std::abs(r));
  }
  return f;
}

std::string upload_profile_toml(const UploadFit& fit, const std::vector<UploadSample>& samples, const std::string& source) {
  std::string t = fmt::format("# GPU upload (vtsim gl calibrate-upload): {}\n", source);
  t += "# model: a frame's copies take per_frame_us + tiles x (per_tile_us + page bytes / link_MBps); least squares per page\n";
  t += fmt::format("# per_frame_us = {:.2f} (the frame's own cost: not a config key, the simulated clock has no per-frame upload term)\n",
                   fit.per_frame_us);
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
