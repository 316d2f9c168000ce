// Upload of validated blobs to GL buffers and their binding as SSBOs or
// buffer textures (bindings.hpp).
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include "decal/gl/gl.hpp"

namespace decal::gl {

namespace {

constexpr uint32_t kSlots = static_cast<uint32_t>(Binding::poly_root_node) + 1;

// Buffer-texture format of a blob: the element type's texel format; records
// are read as several texels (bindings.hpp).
GLenum texture_format(BlobId id) {
  const BlobInfo* info = find_blob_info(id);
  if (id == BlobId::line_props || id == BlobId::dyn_line_props || id == BlobId::poly_props)
    return GL_RGBA32UI;
  if (id == BlobId::line_corners) return GL_RG32F;
  switch (info ? info->type : ElementType::u32) {
    case ElementType::ivec2: return GL_RG32I;
    case ElementType::uvec2: return GL_RG32UI;
    case ElementType::ivec4: return GL_RGBA32I;
    case ElementType::uvec4: return GL_RGBA32UI;
    case ElementType::i32: return GL_R32I;
    case ElementType::f32: return GL_R32F;
    default: return GL_R32UI;
  }
}

}  // namespace

GpuPackage::GpuPackage() = default;

GpuPackage::~GpuPackage() {
  for (auto& s : slots_) {
    if (s.texture) glDeleteTextures(1, &s.texture);
    if (s.buffer) glDeleteBuffers(1, &s.buffer);
  }
}

Status GpuPackage::upload(std::span<const BlobBytes> blobs, const Grid& grid,
                          std::unique_ptr<GpuPackage>& out, bool validated) {
  // No GL call before the data passed every structural check.
  if (!validated)
    if (Status s = validate_blobs(blobs, grid); !s) return s;
  auto pkg = std::unique_ptr<GpuPackage>(new GpuPackage());
  pkg->grid_ = grid;
  pkg->slots_.resize(kSlots);
  std::vector<const BlobBytes*> by_slot(kSlots, nullptr);
  for (const auto& b : blobs) {
    Binding bind = binding_of(b.id);
    if (bind != Binding::none) by_slot[static_cast<uint32_t>(bind)] = &b;
  }
  GLint max_texels = 0;
  glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &max_texels);
  for (uint32_t i = 0; i < kSlots; ++i) {
    Slot& slot = pkg->slots_[i];
    const BlobBytes* b = by_slot[i];
    glCreateBuffers(1, &slot.buffer);
    // Empty blobs still get storage so every binding point is valid.
    const auto size = static_cast<GLsizeiptr>(b && !b->bytes.empty() ? b->bytes.size() : 16);
    glNamedBufferStorage(slot.buffer, size, b && !b->bytes.empty() ? b->bytes.data() : nullptr, 0);
    if (b) {
      slot.count = b->count;
      pkg->bytes_ += b->bytes.size();
    }
    BlobId id = b ? b->id : BlobId::line_vertices;
    if (!b) {
      for (const auto& info : kBlobCatalogue)
        if (static_cast<uint32_t>(binding_of(info.id)) == i) id = info.id;
    }
    // Buffer textures are optional: skip blobs beyond the texel limit (the
    // SSBO path still works; bind(texture) then reports through GL).
    if (static_cast<int64_t>(size / 4) <= max_texels) {
      glCreateTextures(GL_TEXTURE_BUFFER, 1, &slot.texture);
      glTextureBuffer(slot.texture, texture_format(id), slot.buffer);
    }
  }
  if (GLenum e = glGetError(); e != GL_NO_ERROR)
    return Status::failure("gl loader: GL error 0x" + std::to_string(e) +
                           " while uploading blobs (out of memory?)");
  out = std::move(pkg);
  return Status::success();
}

void GpuPackage::bind(BindingMode mode) const {
  for (uint32_t i = 0; i < slots_.size(); ++i) {
    if (mode == BindingMode::ssbo)
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, i, slots_[i].buffer);
    else
      glBindTextureUnit(i, slots_[i].texture);
  }
}

uint64_t GpuPackage::count(BlobId id) const {
  Binding b = binding_of(id);
  if (b == Binding::none || slots_.empty()) return 0;
  return slots_[static_cast<uint32_t>(b)].count;
}

}  // namespace decal::gl
