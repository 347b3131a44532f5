#pragma once
// The GPU upload's calibration (`vtsim gl calibrate-upload`, docs/gpu.md "Calibrating the GPU
// upload"): the simulated clock's copy model, time = upload.per_tile_us + bytes / upload.link_MBps
// (device_model.h, upload_ticks), fitted to measured frames of copies. GL-free: the measuring is in
// src/gl/gl_calibrate.h, the fit and the profile here.
#include <cstdint>
#include <string>
#include <vector>

namespace vtsim {

// One measured point: `tiles` pages of `bytes` each copied in one frame, the frame's copy time
// (the median over repetitions).
struct UploadSample {
  std::uint64_t bytes = 0;  // one page, bytes (payload + borders × channels)
  int tiles = 0;            // pages copied in the frame
  double us = 0.0;          // the frame's copy time, microseconds
  double weight = 1.0;      // in the least squares (calibrate-upload: the store's own page 4x)
};

struct UploadFit {
  double per_tile_us = 0.0;  // fixed cost per page, us (>= 0)
  double MBps = 0.0;         // bytes per us; 0 = the per-byte cost is nil (an unlimited link)
  double per_frame_us = 0.0;  // a frame's fixed cost (query, fence), us (>= 0): reported, not a config key
  // Per sample, in order: the model's frame time and (model − measured) / measured.
  std::vector<double> model_us, rel_residual;
  double max_abs_rel = 0.0;  // the largest |rel_residual|
  std::vector<std::string> notes;  // constraints applied (a negative term clamped to 0)
};

// Weighted non-negative least squares of the per-page time (us / tiles) against the page's bytes
// and the batch: us / tiles = a + b · bytes + c / tiles (c: the frame's fixed cost), a, b, c >= 0
// (of the fits on each subset of the terms with no negative coefficient, the least squared error;
// a term left out is said in notes). MBps = 1 / b (0 when b = 0). Recovers a, b and c exactly (to
// rounding) from samples the model generated. Throws std::invalid_argument for no samples, a
// sample with tiles < 1, a time that is not finite and >= 0 or a weight that is not > 0.
UploadFit fit_upload_model(const std::vector<UploadSample>& samples);

// The profile: an [upload] table of config keys (per_tile_us, link_MBps) for `-c`, with the
// measurements and residuals as comments. `source` names what was timed (renderer, clock).
// Merges with `vtsim calibrate`'s profile (disk, decode, io): pass both with -c.
std::string upload_profile_toml(const UploadFit& fit, const std::vector<UploadSample>& samples, const std::string& source);

}  // namespace vtsim
