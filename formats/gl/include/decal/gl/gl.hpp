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
#include "decal/reader.hpp"  // decal::Status

namespace decal { class Package; }

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

// Builds a program. Each stage's source is "#version 450 core", then
// `defines` (one "#define X" per line), then the named shader files in order
// (later files may use what earlier ones declare). Empty name lists skip the
// stage. `out` holds the GL program name on success.
struct ProgramSources {
  std::vector<std::string> vertex, geometry, fragment, compute;
  std::string defines;
};
Status build_program(const ProgramSources& sources, uint32_t& out);

// ---------------------------------------------------------------- blobs ----

// Blob bytes as the renderer sees them (from a Package or a model in memory).
struct BlobBytes {
  BlobId id{};
  uint64_t count = 0;  // elements
  std::span<const std::byte> bytes;  // count * catalogue stride, 4-byte aligned
};

// The decal grid (thesis Eq. 4.3/4.4), in quanta relative to the origin.
struct Grid {
  int64_t origin_x = 0, origin_y = 0;
  int64_t cell_w = 1, cell_h = 1;
  uint32_t nx = 0, ny = 0;
};

// Structural checks every shader access relies on (thesis §4.2.1 layouts):
// sizes against the catalogue stride, one range per grid cell, every
// (first, count) range inside its list, every vertex / node / polygon / line
// index inside its blob, quad-tree children after their parent (so descent
// terminates), BVH slots inside the box blob, node types 0..3, prev/next
// indices of dynamic lines. Makes no GL call. Returns the first violation,
// naming blob, element and value.
Status validate_blobs(std::span<const BlobBytes> blobs, const Grid& grid);

#ifdef DECAL_GL_HAVE_READER
// The blobs of an opened package (known ids only).
std::vector<BlobBytes> blobs_of(const Package& package);
#endif

// Blobs uploaded to GL buffers, one buffer per blob. Missing blobs get an
// empty 16-byte buffer so that every binding point is valid.
class GpuPackage {
 public:
  GpuPackage();
  ~GpuPackage();
  GpuPackage(const GpuPackage&) = delete;
  GpuPackage& operator=(const GpuPackage&) = delete;

  // Validates (validate_blobs) and, only when that passes, uploads. Needs a
  // current Context.
  static Status upload(std::span<const BlobBytes> blobs, const Grid& grid,
                       std::unique_ptr<GpuPackage>& out);

  // Binds every blob buffer at its Binding (bindings.hpp), as SSBOs or as
  // buffer textures.
  void bind(BindingMode mode) const;

  const Grid& grid() const { return grid_; }
  uint64_t count(BlobId id) const;     // elements uploaded for this blob (0: absent)
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
