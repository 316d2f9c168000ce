// Headless EGL context (ENV-NOTES "Headless OpenGL"): surfaceless Mesa
// platform first, EGL_EXT_platform_device as a fallback; no surface, no
// config (EGL_KHR_no_config_context), rendering into FBOs.
#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <cstdio>
#include <string>

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include "decal/gl/gl.hpp"

namespace decal::gl {

namespace {

std::string egl_error(const char* step) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%s failed (EGL error 0x%04x)", step,
                static_cast<unsigned>(eglGetError()));
  return buf;
}

bool has_extension(const char* list, const char* name) {
  if (!list) return false;
  std::string_view all(list), want(name);
  size_t pos = 0;
  while ((pos = all.find(want, pos)) != std::string_view::npos) {
    size_t end = pos + want.size();
    if ((pos == 0 || all[pos - 1] == ' ') && (end == all.size() || all[end] == ' ')) return true;
    pos = end;
  }
  return false;
}

// Initialises `dpy`; terminates it and returns false when it does not work.
bool try_initialize(EGLDisplay dpy) {
  if (dpy == EGL_NO_DISPLAY) return false;
  EGLint major = 0, minor = 0;
  if (eglInitialize(dpy, &major, &minor) == EGL_TRUE) return true;
  return false;
}

}  // namespace

Context::Context() = default;

Context::~Context() {
  if (display_) {
    auto dpy = static_cast<EGLDisplay>(display_);
    eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (context_) eglDestroyContext(dpy, static_cast<EGLContext>(context_));
    eglTerminate(dpy);
  }
}

Status Context::create(std::unique_ptr<Context>& out) {
  auto ctx = std::unique_ptr<Context>(new Context());
  const char* client_ext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  std::string why;

  EGLDisplay dpy = EGL_NO_DISPLAY;
  if (has_extension(client_ext, "EGL_MESA_platform_surfaceless")) {
    dpy = eglGetPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    if (try_initialize(dpy)) {
      ctx->info_.platform = "surfaceless";
    } else {
      why = egl_error("surfaceless eglInitialize");
      dpy = EGL_NO_DISPLAY;
    }
  } else {
    why = "EGL_MESA_platform_surfaceless not offered";
  }
  if (dpy == EGL_NO_DISPLAY && has_extension(client_ext, "EGL_EXT_platform_device")) {
    auto query_devices =
        reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    EGLDeviceEXT devices[8];
    EGLint n = 0;
    if (query_devices && query_devices(8, devices, &n) == EGL_TRUE) {
      for (EGLint i = 0; i < n && dpy == EGL_NO_DISPLAY; ++i) {
        EGLDisplay d = eglGetPlatformDisplay(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
        if (try_initialize(d)) {
          dpy = d;
          ctx->info_.platform = "device";
        }
      }
    }
    if (dpy == EGL_NO_DISPLAY) why += "; " + egl_error("EGL_EXT_platform_device display");
  }
  if (dpy == EGL_NO_DISPLAY) {
    if (!client_ext)
      why = egl_error("eglQueryString(EGL_EXTENSIONS)") + " (no EGL vendor library?)";
    return Status::failure("gl loader: no headless EGL display could be created: " + why);
  }
  ctx->display_ = dpy;

  const char* dpy_ext = eglQueryString(dpy, EGL_EXTENSIONS);
  if (!has_extension(dpy_ext, "EGL_KHR_surfaceless_context"))
    return Status::failure("gl loader: EGL display lacks EGL_KHR_surfaceless_context");
  if (eglBindAPI(EGL_OPENGL_API) != EGL_TRUE)
    return Status::failure("gl loader: " + egl_error("eglBindAPI(OpenGL)"));
  const EGLint attribs[] = {EGL_CONTEXT_MAJOR_VERSION,
                            4,
                            EGL_CONTEXT_MINOR_VERSION,
                            5,
                            EGL_CONTEXT_OPENGL_PROFILE_MASK,
                            EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                            EGL_NONE};
  EGLContext glc = eglCreateContext(dpy, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attribs);
  if (glc == EGL_NO_CONTEXT)
    return Status::failure("gl loader: " + egl_error("eglCreateContext(GL 4.5 core)"));
  ctx->context_ = glc;
  if (eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, glc) != EGL_TRUE)
    return Status::failure("gl loader: " + egl_error("eglMakeCurrent"));

  auto str = [](GLenum e) {
    const auto* s = reinterpret_cast<const char*>(glGetString(e));
    return std::string(s ? s : "?");
  };
  ctx->info_.vendor = str(GL_VENDOR);
  ctx->info_.renderer = str(GL_RENDERER);
  ctx->info_.version = str(GL_VERSION);
  out = std::move(ctx);
  return Status::success();
}

}  // namespace decal::gl
