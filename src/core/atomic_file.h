#pragma once
// Outputs written whole or not at all (docs/robustness.md "Outputs"): every file vtsim writes is
// first written to a temporary file beside the target, in the same directory (so the rename stays
// on one file system), and renamed over the target only once it is complete. A run that fails or
// is killed leaves the previous file as it was; one that fails removes its temporary file (a
// killed one cannot: its temporary is the hidden ".NAME.tmp-XXXXXX", never the target's name).
#include <functional>
#include <string>
#include <string_view>

namespace vtsim {

class AtomicFile {
 public:
  // Creates the temporary file "DIR/.NAME.tmp-XXXXXX" (mode 0666 less the umask, as a plain
  // create). keep_extension appends NAME's extension ("DIR/.a.png.tmp-XXXXXX.png"): for writers
  // that choose the format by the file name (image files). Throws InputError naming `path`.
  explicit AtomicFile(const std::string& path, bool keep_extension = false);
  ~AtomicFile();  // removes the temporary file unless committed
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  const std::string& path() const { return path_; }
  const std::string& temp_path() const { return temp_; }
  // The temporary's descriptor (write position at the start), -1 after close_fd() or commit().
  int fd() const { return fd_; }
  // Appends `bytes` at the descriptor's position. Throws InputError naming the target.
  void write(std::string_view bytes);
  // Closes the descriptor, for writers that open the temporary again by its name.
  void close_fd();
  // fsync()s the temporary, renames it over the target and fsync()s the directory. Throws
  // InputError naming the target (the temporary is then removed by the destructor).
  void commit();

 private:
  std::string path_, temp_;
  int fd_ = -1;
  bool committed_ = false;
};

// Whether a file name is an AtomicFile's temporary (".NAME.tmp-XXXXXX[.EXT]"): what a killed run
// leaves behind, for directories vtsim owns (a sweep's parts/) to clean up.
bool is_atomic_temp_name(const std::string& filename);

// Output directories, one rule for every command (README.md "Conventions"): the last level is
// created, its parent must exist. check_output_dir() throws InputError(flag, ...) when `dir` cannot
// be one (it exists and is not a writable directory, or its parent is missing, not a directory or
// not writable) and creates nothing: for the checks before the work. make_output_dir() makes the
// same checks, then creates the last level unless it exists.
void check_output_dir(const std::string& flag, const std::string& dir);
void make_output_dir(const std::string& flag, const std::string& dir);

// Writes `text` to `path` through an AtomicFile. Throws InputError naming `path`.
void write_file_atomic(const std::string& path, std::string_view text);
// For writers that take a path: write(temp) fills the temporary file by its name, then it is
// renamed over `path`. An exception from write() leaves `path` as it was.
void write_file_atomic_via(const std::string& path, const std::function<void(const std::string& temp)>& write,
                           bool keep_extension = false);

}  // namespace vtsim
