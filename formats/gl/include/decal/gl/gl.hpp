// decal/gl/gl.hpp — the headless GL loader: an EGL context without a display
// server, validation of package blobs, their upload to GL buffers and the
// embedded GLSL of the decal passes.
//
// Untrusted input: validate_blobs() checks every size, range and index the
// shaders will follow before any GL call sees the data, and upload() refuses
// data that did not pass. Nothing here throws (std::bad_alloc aside); every
// failure is a decal::Status with a one-line message. Thread-safety: a
// Context is current on the thread that created it; GL objects belong to it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "decal/format.hpp"
#include "decal/gl/bindings.hpp"
#include "decal/inspect.hpp"  // BlobBytes, Grid, validate_blobs
#include "decal/reader.hpp"   // decal::Status

namespace decal {
class Package;
}

namespace decal::gl {

// ------------------------------------------------------------------ context --

struct ContextInfo {
  std::string platform;  // "surfaceless" or "device"
  std::string vendor, renderer, version;
};

// A headless OpenGL 4.5 core context made current on the calling thread:
// eglGetPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA), else the first
// EGL_EXT_platform_device device; no surface (EGL_KHR_surfaceless_context),
// EGL_NO_CONFIG_KHR. Rendering goes to framebuffer objects.
class Context {
 public:
  Context();
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  // Fails with a message naming the EGL step and error code when no display
  // or context can be created (e.g. no Mesa driver installed).
  static Status create(std::unique_ptr<Context>& out);
  const ContextInfo& info() const { return info_; }

 private:
  void* display_ = nullptr;
  void* context_ = nullptr;
  ContextInfo info_;
};

// ----------------------------------------------------------------- programs --

// The GLSL file `name` from formats/gl/shaders (embedded at build time), or
// an empty view when there is none.
std::string_view shader_source(std::string_view name);

// The GLSL lines of bindings.hpp's table: DECAL_BLOBS_QUADTREE, _POLYGONS,
// _LINES and _DYNAMIC (the blobs' DECAL_BLOB(index, sampler, name, element)
// declarations, expanded by decal_blobs.glsl) and one "#define MACRO index"
// per kFrameBindings row.
std::string glsl_bindings();

// Builds a program. Each stage's source is "#version 450 core", then
// `defines` (one "#define X" per line), then glsl_bindings(), then the named shader files in order
// (later files may use what earlier ones declare). Empty name lists skip the
// stage. `out` holds the GL program name on success.
struct ProgramSources {
  std::vector<std::string> vertex, geometry, fragment, compute;
  std::string defines;
};
Status build_program(const ProgramSources& sources, uint32_t& out);

// ---------------------------------------------------------------- blobs ----

// Blob bytes and grid as the renderer sees them (decal/inspect.hpp).
using BlobBytes = decal::BlobBytes;
using Grid = decal::Grid;

// The package's structural check (decal::validate_blobs, with the grid) as
// every shader access relies on it; messages start "gl loader: invalid
// package: " and name blob, element and value. Makes no GL call.
Status validate_blobs(std::span<const BlobBytes> blobs, const Grid& grid);

// The blobs of an opened package (known ids only).
using decal::blobs_of;

// Blobs uploaded to GL buffers, one buffer per blob. Missing blobs get an
// empty 16-byte buffer so that every binding point is valid.
class GpuPackage {
 public:
  GpuPackage();
  ~GpuPackage();
  GpuPackage(const GpuPackage&) = delete;
  GpuPackage& operator=(const GpuPackage&) = delete;

  // Validates (validate_blobs) and, only when that passes, uploads. Needs a
  // current Context. `validated`: the caller has already run
  // validate_blobs on exactly these blobs with this grid and it passed (so
  // it runs once per draw); never set it for data not checked that way.
  static Status upload(std::span<const BlobBytes> blobs, const Grid& grid,
                       std::unique_ptr<GpuPackage>& out, bool validated = false);

  // Binds every blob buffer at its Binding (bindings.hpp), as SSBOs or as
  // buffer textures.
  void bind(BindingMode mode) const;

  const Grid& grid() const { return grid_; }
  uint64_t count(BlobId id) const;  // elements uploaded for this blob (0: absent)
  uint64_t bytes_uploaded() const { return bytes_; }

 private:
  struct Slot {
    uint32_t buffer = 0, texture = 0;
    uint64_t count = 0;
  };
  std::vector<Slot> slots_;  // indexed by Binding value
  Grid grid_;
  uint64_t bytes_ = 0;
};

}  // namespace decal::gl
