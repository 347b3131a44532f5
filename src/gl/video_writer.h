#pragma once
// A video of a run's frames (`vtsim gl replay --video FILE`): raw RGBA frames piped to an ffmpeg
// child process (ffmpeg -f rawvideo ... -i pipe:0), which encodes them (H.264 in yuv420p for .mp4 /
// .mkv / .mov, VP9 for .webm, the container by FILE's extension) into a temporary file beside FILE;
// finish() waits for ffmpeg and renames the temporary over FILE only when ffmpeg succeeded
// (core/atomic_file.h: a failed or killed run leaves an existing FILE as it was).
// Thread-safety: none (one thread, the frame loop's). SIGPIPE is blocked in the calling thread
// while it writes to the pipe, so an ffmpeg that exits early is an error, not a signal.
#include <cstdint>
#include <memory>
#include <string>

namespace vtsim {

class AtomicFile;

class VideoWriter {
 public:
  // Starts ffmpeg for frames of width × height RGBA8 pixels, bottom row first (glReadPixels'
  // order; the video is flipped upright), at `fps` frames per second. Throws InputError(flag, ...)
  // when ffmpeg is not on PATH ("install ffmpeg"), the size is odd (yuv420p needs even sides) or
  // the file cannot be created.
  VideoWriter(const std::string& flag, const std::string& path, int width, int height, double fps);
  ~VideoWriter();  // a writer not finished: ffmpeg is stopped, the temporary removed
  VideoWriter(const VideoWriter&) = delete;
  VideoWriter& operator=(const VideoWriter&) = delete;

  // One frame of width·height·4 bytes. Throws InputError when ffmpeg has exited (its last
  // message in the error).
  void add(const std::uint8_t* rgba);
  // Closes the pipe, waits for ffmpeg, renames the file into place. Throws InputError with
  // ffmpeg's last message when it failed.
  void finish();
  std::uint64_t frames() const { return frames_; }

 private:
  std::string ffmpeg_error() const;
  std::string flag_, path_;
  int width_, height_;
  std::unique_ptr<AtomicFile> out_;
  std::string log_;  // ffmpeg's stderr, a temporary file
  int pipe_ = -1;
  long pid_ = -1;
  std::uint64_t frames_ = 0;
};

}  // namespace vtsim
