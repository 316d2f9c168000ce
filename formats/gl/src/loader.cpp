// Upload of validated blobs to GL buffers and their binding as SSBOs or
// buffer textures (bindings.hpp).
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <algorithm>
#include <cstring>

#include "decal/gl/gl.hpp"
#include "decal/layout.hpp"

namespace decal::gl {

namespace {

constexpr uint32_t kSlots = kBlobBindingSlots;

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

// The blobs in the v1.3 layout the shaders read (SPEC.md "Compact layout
// (v1.3)"): the per-cell ranges and leaf segments of older files and of
// models in memory encoded as cell_*_first and leaf loops, in `store`.
struct Encoded {
  std::vector<BlobBytes> blobs;
  std::vector<std::vector<std::byte>> store;
};

template <class T>
std::span<const T> elements(const BlobBytes* b) {
  if (!b) return {};
  return {reinterpret_cast<const T*>(b->bytes.data()), static_cast<size_t>(b->count)};
}

Status encode_v13(std::span<const BlobBytes> in, const Grid& grid, Encoded& out) {
  namespace L = layout;
  auto find = [&](BlobId id) -> const BlobBytes* {
    for (const auto& b : in)
      if (b.id == id) return &b;
    return nullptr;
  };
  std::vector<BlobId> replaced;
  bool ok = true;
  auto add = [&](BlobId id, std::vector<std::byte> bytes, uint64_t count) {
    out.store.push_back(std::move(bytes));
    out.blobs.push_back({id, count, out.store.back()});
    replaced.push_back(id);
  };
  auto bytes_of = [](const auto& v) {
    std::vector<std::byte> b(v.size() * sizeof(v[0]));
    if (!b.empty()) std::memcpy(b.data(), v.data(), b.size());
    return b;
  };
  const L::CellGrid cg{grid.origin_x, grid.origin_y, grid.cell_w, grid.cell_h, grid.nx};
  using I4 = std::array<int32_t, 4>;
  auto cells = [&](BlobId range_id, BlobId bvh_id, BlobId list_id, BlobId box_id, BlobId first_id,
                   BlobId box16_id) {
    const BlobBytes *r = find(range_id), *t = find(bvh_id), *l = find(list_id), *x = find(box_id);
    if (!r || r->count == 0) return;
    const size_t le = find_blob_info(list_id)->stride, be = sizeof(I4);
    L::CellEncoding e = L::encode_cells(elements<L::u2>(r), elements<L::u4>(t),
                                        l ? l->bytes : std::span<const std::byte>{}, le,
                                        x ? x->bytes : std::span<const std::byte>{}, be);
    replaced.push_back(range_id);
    replaced.push_back(bvh_id);
    replaced.push_back(box_id);
    if (!e.ok) ok = false;        // cannot happen after validate_blobs
    if (e.first.empty()) return;  // no entries: the kind is absent
    std::span<const I4> boxes = elements<I4>(x);
    if (!e.boxes.empty())
      boxes = {reinterpret_cast<const I4*>(e.boxes.data()), e.boxes.size() / be};
    const std::vector<L::u2> b16 = L::encode_boxes16(e.first, boxes, cg);
    add(box16_id, bytes_of(b16), b16.size());
    const uint64_t n = e.first.size();
    add(first_id, bytes_of(e.first), n);
    if (!e.list.empty()) {
      const uint64_t nl = e.list.size() / le;
      add(list_id, std::move(e.list), nl);
    }
  };
  cells(BlobId::cell_segment_range, BlobId::line_bvh_range, BlobId::cell_segments,
        BlobId::line_bvh_box, BlobId::cell_line_first, BlobId::line_bvh_box16);
  cells(BlobId::cell_poly_range, BlobId::poly_bvh_range, BlobId::cell_polys, BlobId::poly_bvh_box,
        BlobId::cell_poly_first, BlobId::poly_bvh_box16);
  if (!ok) return Status::failure("gl loader: per-cell ranges break the index constraints");
  // v1.2 exterior entries: the (possibly reordered) cell_polys as entries and
  // hole firsts.
  if (std::find(replaced.begin(), replaced.end(), BlobId::cell_poly_first) != replaced.end() ||
      find(BlobId::cell_polys)) {
    const BlobBytes* cp = nullptr;
    for (const auto& b : out.blobs)
      if (b.id == BlobId::cell_polys) cp = &b;
    if (!cp) cp = find(BlobId::cell_polys);
    const BlobBytes* ch = find(BlobId::cell_holes);
    if (cp && cp->count > 0) {
      L::PolyEntryEncoding e = L::encode_poly_entries(elements<L::u4>(cp), elements<L::u2>(ch));
      if (!e.ok)
        return Status::failure("gl loader: cell_polys hole ranges break the index constraints");
      const uint64_t ne = e.entries.size(), nh = e.hole_first.size();
      add(BlobId::cell_poly_entries, bytes_of(e.entries), ne);
      add(BlobId::cell_poly_holes, bytes_of(e.hole_first), nh);
      if (!e.holes.empty()) {
        const uint64_t n = e.holes.size();
        add(BlobId::cell_holes, bytes_of(e.holes), n);
      }
      std::erase_if(out.blobs, [](const BlobBytes& b) { return b.id == BlobId::cell_polys; });
      replaced.push_back(BlobId::cell_polys);
    }
  }
  const BlobBytes *lr = find(BlobId::qt_leaf_range), *ls = find(BlobId::qt_leaf_segments);
  if ((lr && lr->count) || (ls && ls->count)) {
    const BlobBytes* lv = find(BlobId::qt_leaf_vertices);
    std::vector<L::u2> loop_range;
    std::vector<uint32_t> loop_end;
    if (!L::encode_leaves(elements<L::u2>(lr), elements<L::u2>(ls), lv ? lv->count : 0, loop_range,
                          loop_end))
      return Status::failure(
          "gl loader: quad-tree leaf segments are not closed runs of consecutive vertices; the "
          "shaders read leaf loops only (SPEC.md \"Compact layout (v1.3)\")");
    const uint64_t nr = loop_range.size(), ne = loop_end.size();
    add(BlobId::qt_leaf_loop_range, bytes_of(loop_range), nr);
    add(BlobId::qt_leaf_loops, bytes_of(loop_end), ne);
    replaced.push_back(BlobId::qt_leaf_range);
    replaced.push_back(BlobId::qt_leaf_segments);
  }
  for (const auto& b : in)
    if (std::find(replaced.begin(), replaced.end(), b.id) == replaced.end()) out.blobs.push_back(b);
  return Status::success();
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
  Encoded encoded;
  encoded.store.reserve(16);  // spans into it stay valid
  if (Status s = encode_v13(blobs, grid, encoded); !s) return s;
  auto pkg = std::unique_ptr<GpuPackage>(new GpuPackage());
  pkg->grid_ = grid;
  pkg->slots_.resize(kSlots);
  std::vector<const BlobBytes*> by_slot(kSlots, nullptr);
  for (const auto& b : encoded.blobs) {
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
