#pragma once
// Feedback traces (docs/feedback.md): what an engine's feedback pass saw, frame by frame — the
// frame's time, the camera pose (optional), and the tiles its samples requested with their levels
// and sample counts at the engine's feedback resolution. `vtsim replay --record-feedback` writes
// one from vtsim's own view, `vtsim replay --feedback` replays the streaming side from one.
//
// Binary, little-endian: an 80-byte header, then blocks of frames (each zstd-compressed, with a
// 64-bit FNV-1a checksum of its uncompressed bytes), then an end record with the frame count, so
// that a file cut at a block boundary is refused too. Tile addresses are 64-bit (x, y at their
// level). The reader treats the file as untrusted: every field is checked against the header
// (levels, tiles inside the texture, layers), frames in order, sizes bounded before allocating;
// any fault throws InputError naming "file:frame N" (or "file:header", "file:block at byte B")
// and the field. Thread-safety: none (one reader or writer per thread).
#include <cstdint>
#include <fstream>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

#include "core/trace.h"
#include "core/view.h"
#include "core/view_spans.h"

namespace vtsim {

class AtomicFile;

inline constexpr std::uint32_t kFeedbackVersion = 1;
inline constexpr std::size_t kFeedbackHeaderBytes = 80;
// Bounds that keep a hostile file from asking for huge allocations.
inline constexpr std::uint32_t kFeedbackMaxFramesPerBlock = 4096;
inline constexpr std::uint32_t kFeedbackMaxBlockBytes = 256u << 20;  // uncompressed or compressed

struct FeedbackHeader {
  TextureExtent texture{0, 0};     // level-0 texels
  std::uint32_t tile_size = 128;   // texels a side of a tile (a VT page's payload)
  std::uint32_t levels = 1;        // mip levels of the texture (tiles' levels are below it)
  std::uint32_t layers = 1;        // layers a tile address may name (requests are per page: layer 0)
  std::uint32_t feedback_width = 0, feedback_height = 0;  // the feedback buffer, pixels
  std::uint32_t image_width = 0, image_height = 0;        // the full-resolution image, pixels
  double frame_rate = 60.0;        // frames a second of the recording

  // Tiles a side at `level` (ceil of the level's texels over the tile size, at least 1).
  std::uint64_t tiles_x(int level) const;
  std::uint64_t tiles_y(int level) const;
};

struct FeedbackTile {
  std::uint32_t level = 0;
  std::uint32_t layer = 0;
  std::uint64_t x = 0, y = 0;    // tile address at its level
  std::uint32_t samples = 0;     // feedback samples that requested it (>= 1)
  bool operator==(const FeedbackTile&) const = default;
};

struct FeedbackFrame {
  double t_s = 0.0;          // seconds from the start; strictly increasing
  bool has_pose = false;
  Pose pose;                 // when has_pose (pose.t_s = t_s)
  bool fresh = true;         // the feedback was rendered this frame (false: the last one stands in)
  bool measured = true;      // pop-in is measured at this frame
  std::vector<FeedbackTile> tiles;  // sorted by (layer, level, x, y), distinct; empty unless fresh
};

// The tiles a feedback buffer's samples request, as a virtual texture with unbiased feedback sees
// them: each sample's tile at its desired level (span.level), sorted, samples summed (what
// VtSystem's wanted set starts from). A span inside one tile counts at once; one across tiles is
// expanded sample by sample. `out` is cleared first.
void feedback_tiles(const SpanBuffer& sb, std::uint32_t tile_size, std::vector<FeedbackTile>& out);

class FeedbackWriter {
 public:
  // Throws InputError(path, ...) when the file cannot be written.
  FeedbackWriter(const std::string& path, const FeedbackHeader& h, std::uint32_t frames_per_block = 64);
  ~FeedbackWriter();
  FeedbackWriter(const FeedbackWriter&) = delete;
  FeedbackWriter& operator=(const FeedbackWriter&) = delete;
  void add(const FeedbackFrame& f);
  // Flushes the last block and the end record; throws InputError on a write error.
  void finish();
  std::uint64_t frames() const { return frames_; }
  std::uint64_t bytes() const { return bytes_; }

 private:
  void flush_block();
  std::string path_;
  std::unique_ptr<AtomicFile> out_;  // renamed over path_ by finish(); a writer never finished leaves path_ as it was
  FeedbackHeader h_;
  std::uint32_t per_block_;
  std::string raw_;
  std::uint32_t block_frames_ = 0;
  std::uint64_t block_first_ = 0;
  std::uint64_t frames_ = 0, bytes_ = 0;
  double last_t_ = 0.0;
  bool finished_ = false;
};

class FeedbackReader {
 public:
  // Opens a file; throws InputError when it cannot be read or its header is bad.
  explicit FeedbackReader(const std::string& path);
  // Reads from a stream (tests, fuzzing); `name` is the file name errors give.
  FeedbackReader(std::unique_ptr<std::istream> in, std::string name);
  ~FeedbackReader();
  const FeedbackHeader& header() const { return h_; }
  // The next frame into `f`; false after the last one (the end record checked). Throws InputError.
  bool next(FeedbackFrame& f);
  std::uint64_t frame_index() const { return frame_; }  // frames read so far

 private:
  void read_header();
  bool load_block();
  [[noreturn]] void fail(const std::string& field, const std::string& what) const;
  std::unique_ptr<std::istream> in_;
  std::string name_;
  FeedbackHeader h_;
  std::string raw_;           // the current block, uncompressed
  std::size_t pos_ = 0;       // read position in raw_
  std::uint32_t left_ = 0;    // frames left in raw_
  std::uint64_t frame_ = 0;
  std::uint64_t offset_ = kFeedbackHeaderBytes;  // file offset of the next block
  double last_t_ = 0.0;
  bool done_ = false;
};

// Whether the file at `path` starts with the feedback trace's magic (false when unreadable).
bool is_feedback_trace(const std::string& path);
// The frames' poses as a camera trace (a frame without a pose: the identity pose at its time),
// named after the file, source_path = path: what a sweep lists and hashes for a feedback trace.
Trace feedback_trace_poses(const std::string& path);

// A whole file read at once (what `vtsim replay --feedback` and the tests use).
struct FeedbackTrace {
  FeedbackHeader header;
  std::vector<FeedbackFrame> frames;
};
FeedbackTrace read_feedback_trace(const std::string& path);

}  // namespace vtsim
