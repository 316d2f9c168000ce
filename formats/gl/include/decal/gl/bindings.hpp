// decal/gl/bindings.hpp — the GL binding points of the package blobs.
//
// Every blob the renderer reads has one fixed binding index. With SSBO
// binding (the default) it is the shader-storage binding point of a std430
// `readonly buffer`; with buffer-texture binding it is the texture unit of a
// `*samplerBuffer` over the same GL buffer. The GLSL declarations in
// formats/gl/shaders/decal_blobs.glsl use exactly these numbers (a test
// compiles them against this table).
//
// The static pass reads the polygon blobs in one draw and the line blobs in
// another (thesis §4.4.1 renders polygons first, then lines over them); the
// line draw also reads the five quad-tree blobs (qt_*), for the rings of
// clipped outlines (SPEC "Clipped outlines"). Each draw stays within 16
// storage blocks per fragment shader (polygons 12, lines 12). The loader
// uploads the v1.3 layout only (older layouts are encoded on upload, SPEC.md
// "Compact layout (v1.3)"): binding 17, the line BVH ranges of v1.0-1.2,
// stays unused.
//
// Buffer-texture formats (texel per element unless noted):
//   ivec2 -> RG32I, uvec2 -> RG32UI, ivec4 -> RGBA32I, uvec4 -> RGBA32UI,
//   u32 -> R32UI, LineProps / PolyProps -> RGBA32UI (2 texels per element),
//   LineCorner -> RG32F (3 texels per element).
#pragma once

#include <cstdint>

#include "decal/format.hpp"

namespace decal::gl {

enum class Binding : uint32_t {
  // static polygons (polygon draw; qt_* also in the line draw)
  poly_props = 0,
  qt_node_box = 1,
  qt_node = 2,
  qt_leaf_loop_range = 3,
  qt_leaf_loops = 4,
  qt_leaf_vertices = 5,
  cell_poly_first = 6,
  cell_poly_entries = 7,
  cell_holes = 8,
  cell_poly_holes = 9,  // v1.3 (poly_bvh_range before: now derived from cell_poly_first)
  poly_bvh_box16 = 10,
  // static lines (line draw)
  line_vertices = 11,
  line_vertex_line = 12,
  line_props = 13,
  line_corners = 14,
  cell_line_first = 15,
  cell_segments = 16,
  unused_17 = 17,  // line_bvh_range before v1.3 (now derived from cell_line_first)
  line_bvh_box16 = 18,
  // dynamic lines
  dyn_vertices = 19,
  dyn_prev_next = 20,
  dyn_line_start = 21,
  dyn_line_props = 22,
  // polygon roots (their boxes are the polygon bounding boxes; coverage AA)
  poly_root_node = 23,
  none = 0xffffffffu,
};

// Binding of a blob id; Binding::none for blobs the renderer does not read
// (LOD blobs, unknown ids).
constexpr Binding binding_of(BlobId id) {
  switch (id) {
    case BlobId::poly_props: return Binding::poly_props;
    case BlobId::qt_node_box: return Binding::qt_node_box;
    case BlobId::qt_node: return Binding::qt_node;
    case BlobId::qt_leaf_loop_range: return Binding::qt_leaf_loop_range;
    case BlobId::qt_leaf_loops: return Binding::qt_leaf_loops;
    case BlobId::qt_leaf_vertices: return Binding::qt_leaf_vertices;
    case BlobId::cell_poly_first: return Binding::cell_poly_first;
    case BlobId::cell_poly_entries: return Binding::cell_poly_entries;
    case BlobId::cell_poly_holes: return Binding::cell_poly_holes;
    case BlobId::cell_holes: return Binding::cell_holes;
    case BlobId::poly_bvh_box16: return Binding::poly_bvh_box16;
    case BlobId::line_vertices: return Binding::line_vertices;
    case BlobId::line_vertex_line: return Binding::line_vertex_line;
    case BlobId::line_props: return Binding::line_props;
    case BlobId::line_corners: return Binding::line_corners;
    case BlobId::cell_line_first: return Binding::cell_line_first;
    case BlobId::cell_segments: return Binding::cell_segments;
    case BlobId::line_bvh_box16: return Binding::line_bvh_box16;
    case BlobId::dyn_vertices: return Binding::dyn_vertices;
    case BlobId::dyn_prev_next: return Binding::dyn_prev_next;
    case BlobId::dyn_line_start: return Binding::dyn_line_start;
    case BlobId::dyn_line_props: return Binding::dyn_line_props;
    case BlobId::poly_root_node: return Binding::poly_root_node;
    default: return Binding::none;
  }
}

// Renderer-owned bindings (per-frame buffers), above the blob bindings.
inline constexpr uint32_t kBindingFrameFirst = 24;

// Dashed lines (formats/SPEC.md "Dashed lines"): the renderer's dash table
// and the static-line vertices' along-line distances, computed at load, not
// blobs; SSBOs in both binding modes (formats/gl/shaders/dash.glsl). The
// dynamic pass's per-frame dash buffer is binding 40 (dyn_common.glsl).
inline constexpr uint32_t kBindingDashTable = 38;
inline constexpr uint32_t kBindingDashVertex = 39;

// How blobs are exposed to shaders.
enum class BindingMode { ssbo, texture };

}  // namespace decal::gl
