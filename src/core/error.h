#pragma once
// Errors for untrusted input. Every message names where the problem is (file and line, or the
// config field) so the user can fix it; the CLI prints it and exits non-zero.
#include <stdexcept>
#include <string>

namespace vtsim {

class InputError : public std::runtime_error {
 public:
  // where: "path:line", "path: field 'x'", "--set key"...; what: the problem in plain words.
  InputError(const std::string& where, const std::string& what)
      : std::runtime_error(where.empty() ? what : where + ": " + what), where_(where) {}
  const std::string& where() const { return where_; }

 private:
  std::string where_;
};

// Helper for parsers: "file:line".
inline std::string at_line(const std::string& file, long long line) {
  return file + ":" + std::to_string(line);
}

}  // namespace vtsim
