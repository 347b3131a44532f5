#pragma once
// A headless OpenGL 4.5 core context through EGL (docs/gpu.md): a GPU driver's EGL device when
// one is there (EGL_EXT_device_enumeration), else Mesa's surfaceless platform
// (EGL_MESA_platform_surfaceless: llvmpipe from Debian's libegl-mesa0 + libgl1-mesa-dri). GL
// entry points through libepoxy. GL errors and driver warnings arrive through a KHR_debug callback
// (GL 4.3 core) and go to the caller's warning sink.
#include <functional>
#include <memory>
#include <string>

namespace vtsim::gl {

class Context {
 public:
  using WarnFn = std::function<void(const std::string&)>;
  // Creates the context and makes it current on the calling thread (use it from that thread only).
  // Throws InputError("gl", ...) naming what is missing: libEGL.so.1, an EGL display, OpenGL 4.5
  // core, with the Debian packages that provide it. LP_NUM_THREADS is set to 2 when unset
  // (llvmpipe's rasteriser threads; the machines this runs on are shared).
  explicit Context(WarnFn warn);
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  const std::string& renderer() const { return renderer_; }  // GL_RENDERER
  const std::string& version() const { return version_; }    // GL_VERSION
  const std::string& platform() const { return platform_; }  // "device" or "surfaceless"
  // GL errors reported through KHR_debug since the context was made (warnings included).
  int errors() const { return errors_; }

  // Whether a context can be had here; on false, `why` says what is missing (tests exit 77).
  static bool available(std::string* why);

 private:
  struct Egl;
  std::unique_ptr<Egl> egl_;
  WarnFn warn_;
  std::string renderer_, version_, platform_;
  int errors_ = 0;
  static void debug_callback(unsigned source, unsigned type, unsigned id, unsigned severity, int length,
                             const char* message, const void* user);
};

}  // namespace vtsim::gl
