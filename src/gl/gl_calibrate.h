#pragma once
// `vtsim gl calibrate-upload` (docs/gpu.md, "Calibrating the GPU upload"): times the GL client's
// own page copy (StreamedVt::upload: a ring of pixel-unpack buffers, glMapNamedBufferRange +
// glTextureSubImage2D, the frame bracketed by a GL_TIME_ELAPSED query) at batches of pages per
// frame and page sizes around the store's, and fits the simulated clock's copy model
// (stream/exec/upload_fit.h: upload.per_tile_us + bytes / upload.link_MBps) to it.
//
// Per frame of a batch: the wall time of the submitting thread from the first upload to the query's
// end (submit), and to glFinish (complete: on llvmpipe the copy is CPU work, done by then), and the
// GL_TIME_ELAPSED query's time (what a real GPU's copy engine spends; what `gl replay` reports as
// gl.upload_gpu_ms_total). Medians over repetitions, interleaved across batches.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "stream/exec/upload_fit.h"

namespace vtsim::gl {

class Renderer;

struct UploadCalibrateOptions {
  int tile = 128;                        // the store's page payload, texels a side
  int border = 4;                        // the store's border, texels a side
  int channels = 4;                      // 8-bit channels of a texel (layer 0's)
  // Payload sides timed: the store's page and pages of half and twice its side (same border and
  // channels), so that the per-page and per-byte costs can be told apart; empty: those three.
  std::vector<int> tiles;
  std::vector<int> batches = {1, 4, 16, 64};  // pages copied a frame
  int reps = 7;                               // repetitions of each (size, batch); medians
  std::uint64_t seed = 1;                     // the pages' texels
};

struct UploadPoint {
  int tile = 0, border = 0, channels = 0;
  std::uint64_t bytes = 0;  // one page: (tile + 2 border)² × channels
  int batch = 0;            // pages a frame
  int reps = 0;
  double gpu_us = 0;        // median GL_TIME_ELAPSED of the frame's copies
  double submit_us = 0;     // median wall time of the upload calls and the query's end
  double complete_us = 0;   // median wall time to glFinish
};

struct UploadCalibration {
  std::vector<UploadPoint> points;
  UploadFit gpu, cpu;  // fitted to gpu_us and to complete_us
  std::vector<UploadSample> gpu_samples, cpu_samples;
  // The GPU's timer saw the copies: on the frame the submitting thread spent longest on, the
  // query measured at least a tenth of that. llvmpipe copies on the submitting thread, and its
  // GL_TIME_ELAPSED, bracketing no GPU work, reads ~0.
  bool gpu_saw_copies = false;
};

using UploadProgress = std::function<void(const std::string&)>;

// On the current context (`r`: any scene; its texture extent sizes the page table). Throws
// InputError for bad options (a batch outside 1..4096, reps outside 1..1000, a page the GL's
// texture size cannot hold) and std::runtime_error when the timer queries never complete.
UploadCalibration calibrate_upload(Renderer& r, const UploadCalibrateOptions& options, const UploadProgress& progress = {});

}  // namespace vtsim::gl
