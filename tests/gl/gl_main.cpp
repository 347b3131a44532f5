// The `gl` tests' main (ctest label gl): exit 77 (ctest SKIP_RETURN_CODE) when no OpenGL 4.5 core
// context can be had through EGL here, naming what is missing.
#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest/doctest.h>

#include <cstdio>
#include <string>

#include "gl/gl_context.h"

int main(int argc, char** argv) {
  std::string why;
  if (!vtsim::gl::Context::available(&why)) {
    std::fprintf(stderr, "gl tests skipped: %s\n", why.c_str());
    return 77;
  }
  doctest::Context ctx(argc, argv);
  return ctx.run();
}
