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
};

struct UploadFit {
  double per_tile_us = 0.0;  // fixed cost per page, us (>= 0)
  double MBps = 0.0;         // bytes per us; 0 = the per-byte cost is nil (an unlimited link)
  // Per sample, in order: the model's frame time and (model − measured) / measured.
  std::vector<double> model_us, rel_residual;
  double max_abs_rel = 0.0;  // the largest |rel_residual|
  std::vector<std::string> notes;  // constraints applied (a negative term clamped to 0)
};

// Least squares of the per-page time (us / tiles) against the page's bytes: us / tiles = a + b ·
// bytes, every sample weighing alike, with a >= 0 and b >= 0 (a negative intercept refits b
// through the origin; a negative slope fits a alone). MBps = 1 / b. Recovers a and b exactly from
// samples the model generated. Throws std::invalid_argument for no samples, a sample with tiles
// < 1 or a time that is not finite and >= 0.
UploadFit fit_upload_model(const std::vector<UploadSample>& samples);

// The profile: an [upload] table of config keys (per_tile_us, link_MBps) for `-c`, with the
// measurements and residuals as comments. `source` names what was timed (renderer, clock).
// Merges with `vtsim calibrate`'s profile (disk, decode, io): pass both with -c.
std::string upload_profile_toml(const UploadFit& fit, const std::vector<UploadSample>& samples, const std::string& source);

}  // namespace vtsim
