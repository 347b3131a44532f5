#include "gl/video_writer.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include <fmt/format.h>

#include "core/atomic_file.h"
#include "core/error.h"

extern char** environ;

namespace vtsim {

namespace {

bool on_path(const std::string& exe) {
  const char* p = std::getenv("PATH");
  std::stringstream dirs(p ? p : "");
  for (std::string d; std::getline(dirs, d, ':');)
    if (!d.empty() && ::access((d + "/" + exe).c_str(), X_OK) == 0) return true;
  return false;
}

// The codec for a container: VP9 for WebM, H.264 otherwise (mp4, mkv, mov).
std::vector<std::string> codec_args(const std::string& path) {
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext == ".webm") return {"-c:v", "libvpx-vp9", "-b:v", "0", "-crf", "32", "-deadline", "realtime", "-cpu-used", "8"};
  // veryfast: the encoder keeps pace with llvmpipe's frames on two cores; crf 23 is x264's default.
  return {"-c:v", "libx264", "-preset", "veryfast", "-crf", "23", "-movflags", "+faststart"};
}

// Writes all of `n` bytes with SIGPIPE blocked in this thread; returns false on EPIPE or another
// error (errno set). A SIGPIPE raised meanwhile is consumed before it is unblocked.
bool write_all(int fd, const std::uint8_t* p, std::size_t n) {
  sigset_t pipe_set, old;
  sigemptyset(&pipe_set);
  sigaddset(&pipe_set, SIGPIPE);
  pthread_sigmask(SIG_BLOCK, &pipe_set, &old);
  bool ok = true;
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) {
      ok = false;
      break;
    }
    p += w;
    n -= static_cast<std::size_t>(w);
  }
  const int saved = errno;
  if (!ok) {
    const timespec zero{0, 0};
    while (sigtimedwait(&pipe_set, nullptr, &zero) == SIGPIPE) {
    }
  }
  pthread_sigmask(SIG_SETMASK, &old, nullptr);
  errno = saved;
  return ok;
}

}  // namespace

VideoWriter::VideoWriter(const std::string& flag, const std::string& path, int width, int height, double fps)
    : flag_(flag), path_(path), width_(width), height_(height) {
  if (!on_path("ffmpeg"))
    throw InputError(flag, "ffmpeg is not on PATH: install it (Debian: apt-get install ffmpeg) or leave out " + flag);
  if (width < 2 || height < 2 || width % 2 || height % 2)
    throw InputError(flag, fmt::format("the frames are {}x{} pixels: a video needs even sides (yuv420p)", width, height));
  if (!(fps > 0.0)) throw InputError(flag, "the frame rate must be positive");
  out_ = std::make_unique<AtomicFile>(path, true);
  out_->close_fd();
  log_ = out_->temp_path() + ".log";
  std::vector<std::string> args = {"ffmpeg", "-nostdin", "-hide_banner", "-loglevel", "error", "-y",
                                   "-f", "rawvideo", "-pix_fmt", "rgba", "-s", fmt::format("{}x{}", width, height),
                                   "-framerate", fmt::format("{}", fps), "-i", "pipe:0", "-vf", "vflip",
                                   "-pix_fmt", "yuv420p"};
  for (std::string& a : codec_args(path)) args.push_back(std::move(a));
  args.push_back(out_->temp_path());
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) throw InputError(flag, std::string("pipe: ") + std::strerror(errno));
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, fds[0], 0);
  posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 2, log_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, "ffmpeg", &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  ::close(fds[0]);
  if (rc != 0) {
    ::close(fds[1]);
    std::remove(log_.c_str());
    throw InputError(flag, std::string("cannot start ffmpeg: ") + std::strerror(rc));
  }
  pipe_ = fds[1];
  pid_ = pid;
}

VideoWriter::~VideoWriter() {
  if (pipe_ >= 0) ::close(pipe_);
  if (pid_ > 0) {
    ::kill(static_cast<pid_t>(pid_), SIGTERM);
    int st = 0;
    ::waitpid(static_cast<pid_t>(pid_), &st, 0);
  }
  if (!log_.empty()) std::remove(log_.c_str());
  // out_'s destructor removes the temporary (not committed).
}

std::string VideoWriter::ffmpeg_error() const {
  std::ifstream f(log_);
  std::string line, last;
  while (std::getline(f, line))
    if (!line.empty()) last = line;
  return last.empty() ? "no message" : last;
}

void VideoWriter::add(const std::uint8_t* rgba) {
  if (pipe_ < 0) throw std::logic_error("VideoWriter::add after finish");
  const std::size_t n = static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_) * 4;
  if (!write_all(pipe_, rgba, n))
    throw InputError(flag_, fmt::format("{}: ffmpeg stopped taking frames after {}: {}", path_, frames_, ffmpeg_error()));
  ++frames_;
}

void VideoWriter::finish() {
  if (pipe_ < 0) throw std::logic_error("VideoWriter::finish twice");
  ::close(pipe_);
  pipe_ = -1;
  int st = 0;
  pid_t r;
  do r = ::waitpid(static_cast<pid_t>(pid_), &st, 0);
  while (r < 0 && errno == EINTR);
  pid_ = -1;
  if (r < 0 || !WIFEXITED(st) || WEXITSTATUS(st) != 0)
    throw InputError(flag_, fmt::format("{}: ffmpeg failed ({}): {}", path_,
                                        r < 0 ? std::string(std::strerror(errno))
                                              : WIFEXITED(st) ? fmt::format("exit {}", WEXITSTATUS(st))
                                                              : fmt::format("signal {}", WTERMSIG(st)),
                                        ffmpeg_error()));
  if (frames_ == 0) throw InputError(flag_, path_ + ": no frame to encode");
  out_->commit();
  std::remove(log_.c_str());
  log_.clear();
}

}  // namespace vtsim
