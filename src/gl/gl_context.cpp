#include "gl/gl_context.h"

#include <dlfcn.h>
#include <epoxy/egl.h>
#include <epoxy/gl.h>
#include <fmt/format.h>

#include <cstdlib>
#include <cstring>
#include <vector>

#include "core/error.h"

namespace vtsim::gl {

struct Context::Egl {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
};

namespace {

constexpr const char* kPackages = "Debian: libegl1 libegl-mesa0 libgl1-mesa-dri (Mesa's llvmpipe), or a GPU driver's EGL";

[[noreturn]] void missing(const std::string& what) {
  throw InputError("gl", fmt::format("{} ({})", what, kPackages));
}

bool has_ext(const char* list, const char* ext) {
  if (list == nullptr) return false;
  const std::size_t n = std::strlen(ext);
  for (const char* p = list; (p = std::strstr(p, ext)) != nullptr; p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  return false;
}

// A hardware EGL device (one exposing a DRM node), or EGL_NO_DISPLAY.
EGLDisplay device_display() {
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!has_ext(client, "EGL_EXT_device_enumeration") || !has_ext(client, "EGL_EXT_platform_device")) return EGL_NO_DISPLAY;
  EGLint n = 0;
  if (!eglQueryDevicesEXT(0, nullptr, &n) || n <= 0) return EGL_NO_DISPLAY;
  std::vector<EGLDeviceEXT> devs(static_cast<std::size_t>(n));
  if (!eglQueryDevicesEXT(n, devs.data(), &n)) return EGL_NO_DISPLAY;
  for (EGLint i = 0; i < n; ++i) {
    const char* ext = eglQueryDeviceStringEXT(devs[static_cast<std::size_t>(i)], EGL_EXTENSIONS);
    if (!has_ext(ext, "EGL_EXT_device_drm")) continue;  // Mesa's software device has no DRM node
    EGLDisplay d = eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, devs[static_cast<std::size_t>(i)], nullptr);
    EGLint ma = 0, mi = 0;
    if (d != EGL_NO_DISPLAY && eglInitialize(d, &ma, &mi)) return d;
  }
  return EGL_NO_DISPLAY;
}

}  // namespace

bool Context::available(std::string* why) {
  try {
    Context c([](const std::string&) {});
    return true;
  } catch (const InputError& e) {
    if (why) *why = e.what();
    return false;
  }
}

Context::Context(WarnFn warn) : egl_(std::make_unique<Egl>()), warn_(std::move(warn)) {
  setenv("LP_NUM_THREADS", "2", 0);
  // libepoxy dlopens libEGL on its first EGL call and aborts when it cannot: look first.
  if (dlopen("libEGL.so.1", RTLD_LAZY | RTLD_GLOBAL) == nullptr) missing("libEGL.so.1 cannot be loaded");
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  EGLDisplay d = device_display();
  platform_ = "device";
  if (d == EGL_NO_DISPLAY) {
    platform_ = "surfaceless";
    if (!has_ext(client, "EGL_MESA_platform_surfaceless")) missing("EGL has no surfaceless platform (EGL_MESA_platform_surfaceless)");
    d = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    EGLint ma = 0, mi = 0;
    if (d == EGL_NO_DISPLAY || !eglInitialize(d, &ma, &mi))
      missing(fmt::format("no EGL display on the surfaceless platform (EGL error 0x{:x})", eglGetError()));
  }
  egl_->display = d;
  if (!has_ext(eglQueryString(d, EGL_EXTENSIONS), "EGL_KHR_surfaceless_context") ||
      !has_ext(eglQueryString(d, EGL_EXTENSIONS), "EGL_KHR_no_config_context"))
    missing("the EGL display cannot make a context without a surface (EGL_KHR_surfaceless_context, EGL_KHR_no_config_context)");
  if (!eglBindAPI(EGL_OPENGL_API)) missing("EGL has no desktop OpenGL API");
  const EGLint attrs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5, EGL_CONTEXT_OPENGL_PROFILE_MASK,
                          EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_CONTEXT_OPENGL_DEBUG, EGL_TRUE, EGL_NONE};
  egl_->context = eglCreateContext(d, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attrs);
  if (egl_->context == EGL_NO_CONTEXT)
    missing(fmt::format("no OpenGL 4.5 core context (EGL error 0x{:x})", eglGetError()));
  if (!eglMakeCurrent(d, EGL_NO_SURFACE, EGL_NO_SURFACE, egl_->context))
    missing(fmt::format("cannot make the OpenGL context current (EGL error 0x{:x})", eglGetError()));
  if (epoxy_gl_version() < 45) missing(fmt::format("OpenGL {}.{} only, 4.5 needed", epoxy_gl_version() / 10, epoxy_gl_version() % 10));
  renderer_ = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  version_ = reinterpret_cast<const char*>(glGetString(GL_VERSION));
  glEnable(GL_DEBUG_OUTPUT);
  glEnable(GL_DEBUG_OUTPUT_SYNCHRONOUS);
  glDebugMessageCallback(reinterpret_cast<GLDEBUGPROC>(&Context::debug_callback), this);
  // Notifications (buffer placement hints) are not warnings.
  glDebugMessageControl(GL_DONT_CARE, GL_DONT_CARE, GL_DEBUG_SEVERITY_NOTIFICATION, 0, nullptr, GL_FALSE);
}

void Context::debug_callback(unsigned source, unsigned type, unsigned id, unsigned severity, int length,
                             const char* message, const void* user) {
  (void)source;
  (void)severity;
  auto* self = static_cast<Context*>(const_cast<void*>(user));
  if (type == GL_DEBUG_TYPE_ERROR) ++self->errors_;
  const std::string msg(message, length > 0 ? static_cast<std::size_t>(length) : std::strlen(message));
  self->warn_(fmt::format("gl: {} {}: {}", type == GL_DEBUG_TYPE_ERROR ? "error" : "message", id, msg));
}

Context::~Context() {
  if (egl_->display != EGL_NO_DISPLAY) {
    eglMakeCurrent(egl_->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (egl_->context != EGL_NO_CONTEXT) eglDestroyContext(egl_->display, egl_->context);
    eglTerminate(egl_->display);
  }
}

}  // namespace vtsim::gl
