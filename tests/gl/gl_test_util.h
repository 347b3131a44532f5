#pragma once
// The gl tests' one OpenGL context (current on the test thread), and the warnings its KHR_debug
// callback sent.
#include <string>
#include <vector>

#include "gl/gl_context.h"

namespace vtsim::gl_test {

struct Shared {
  std::vector<std::string> warnings;
  gl::Context ctx{[this](const std::string& m) { warnings.push_back(m); }};
};

inline Shared& shared() {
  static Shared s;
  return s;
}

}  // namespace vtsim::gl_test
