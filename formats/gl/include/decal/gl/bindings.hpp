// decal/gl/bindings.hpp — the GL binding points of the package blobs.
//
// Every blob the renderer reads has one fixed binding index. With SSBO
// binding (the default) it is the shader-storage binding point of a std430
// `readonly buffer`; with buffer-texture binding it is the texture unit of a
// `*samplerBuffer` over the same GL buffer. This file is the one list of the
// binding points and texture units the shaders use: build_program puts the
// GLSL declarations of the blobs (DECAL_BLOBS_QUADTREE, _POLYGONS, _LINES,
// _DYNAMIC, expanded by formats/gl/shaders/decal_blobs.glsl) and a #define
// per renderer-owned binding and unit (DECAL_SSBO_*, DECAL_UNIT_*) before
// every shader (glsl_bindings()), and a test compiles them against this
// table (tests/formats/gl_bindings_test.cpp).
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
#include <string_view>

#include "decal/format.hpp"

namespace decal::gl {

// Which passes declare a blob: decal_blobs.glsl expands DECAL_BLOBS_<GROUP>
// where the pass defines DECAL_POLYGONS and/or DECAL_LINES (quadtree: either),
// or DECAL_DYNAMIC.
enum class BlobGroup : uint8_t { quadtree, polygons, lines, dynamic };

// A blob the renderer reads: its binding index and how GLSL declares it
// (`sampler` t_<name> with buffer textures, else a std430 block B_<name> of
// `element`s d_<name>[]; <name> is the catalogue name).
struct BlobBinding {
  BlobId blob;
  uint32_t index;
  BlobGroup group;
  std::string_view sampler;
  std::string_view element;
};

// clang-format off
inline constexpr BlobBinding kBlobBindings[] = {
  // static polygons (polygon draw; qt_* also in the line draw)
  {BlobId::poly_props,         0,  BlobGroup::polygons, "usamplerBuffer", "PolyProps"},
  {BlobId::qt_node_box,        1,  BlobGroup::quadtree, "isamplerBuffer", "ivec4"},
  {BlobId::qt_node,            2,  BlobGroup::quadtree, "isamplerBuffer", "ivec2"},
  {BlobId::qt_leaf_loop_range, 3,  BlobGroup::quadtree, "usamplerBuffer", "uvec2"},
  {BlobId::qt_leaf_loops,      4,  BlobGroup::quadtree, "usamplerBuffer", "uint"},
  {BlobId::qt_leaf_vertices,   5,  BlobGroup::quadtree, "isamplerBuffer", "ivec2"},
  {BlobId::cell_poly_first,    6,  BlobGroup::polygons, "usamplerBuffer", "uvec2"},
  {BlobId::cell_poly_entries,  7,  BlobGroup::polygons, "usamplerBuffer", "uvec2"},
  {BlobId::cell_holes,         8,  BlobGroup::polygons, "usamplerBuffer", "uvec2"},
  {BlobId::cell_poly_holes,    9,  BlobGroup::polygons, "usamplerBuffer", "uint"},
  {BlobId::poly_bvh_box16,     10, BlobGroup::polygons, "usamplerBuffer", "uvec2"},
  // static lines (line draw); 17 unused (line_bvh_range before v1.3)
  {BlobId::line_vertices,      11, BlobGroup::lines,    "isamplerBuffer", "ivec2"},
  {BlobId::line_vertex_line,   12, BlobGroup::lines,    "usamplerBuffer", "uint"},
  {BlobId::line_props,         13, BlobGroup::lines,    "usamplerBuffer", "LineProps"},
  {BlobId::line_corners,       14, BlobGroup::lines,    "samplerBuffer",  "LineCorner"},
  {BlobId::cell_line_first,    15, BlobGroup::lines,    "usamplerBuffer", "uvec2"},
  {BlobId::cell_segments,      16, BlobGroup::lines,    "usamplerBuffer", "uvec2"},
  {BlobId::line_bvh_box16,     18, BlobGroup::lines,    "usamplerBuffer", "uvec2"},
  // dynamic lines
  {BlobId::dyn_vertices,       19, BlobGroup::dynamic,  "isamplerBuffer", "ivec4"},
  {BlobId::dyn_prev_next,      20, BlobGroup::dynamic,  "isamplerBuffer", "ivec2"},
  {BlobId::dyn_line_start,     21, BlobGroup::dynamic,  "usamplerBuffer", "uint"},
  {BlobId::dyn_line_props,     22, BlobGroup::dynamic,  "usamplerBuffer", "LineProps"},
  // polygon roots (their boxes are the polygon bounding boxes; coverage AA)
  {BlobId::poly_root_node,     23, BlobGroup::polygons, "usamplerBuffer", "uint"},
};
// clang-format on

// A blob's binding index; Binding::none for blobs the renderer does not read
// (LOD blobs, superseded blobs, unknown ids).
enum class Binding : uint32_t { none = 0xffffffffu };
constexpr Binding binding_of(BlobId id) {
  for (const BlobBinding& b : kBlobBindings)
    if (b.blob == id) return Binding{b.index};
  return Binding::none;
}

// The blob bindings occupy [0, kBlobBindingSlots).
constexpr uint32_t blob_binding_slots() {
  uint32_t n = 0;
  for (const BlobBinding& b : kBlobBindings) n = b.index + 1 > n ? b.index + 1 : n;
  return n;
}
inline constexpr uint32_t kBlobBindingSlots = blob_binding_slots();

// Renderer-owned bindings (per-frame buffers, G-buffer targets), from 24 up,
// above the blob bindings: X(kind, C++ constant, GLSL macro, index, GLSL
// resource). kind ssbo: a std430 block named `resource` at that binding
// point; unit: a sampler uniform named `resource` on that texture unit. The
// two are separate GL name spaces, and passes that are never one program
// may share an index (SSBO 24: the dynamic pass's flags, the terrain pass's
// gradients; unit 24: the line pass's slope layers; unit 27: the texture
// method's terrain pass and the line pass's minimum widths).
// clang-format off
#define DECAL_GL_FRAME_BINDINGS(X)                                                              \
  X(ssbo, kSsboDynFlags,        "DECAL_SSBO_DYN_FLAGS",        24, "DynFlags")                   \
  X(ssbo, kSsboDynScan,         "DECAL_SSBO_DYN_SCAN",         25, "DynScan")                    \
  X(ssbo, kSsboDynBlocks,       "DECAL_SSBO_DYN_BLOCKS",       26, "DynBlocks")                  \
  X(ssbo, kSsboDynCompact,      "DECAL_SSBO_DYN_COMPACT",      27, "DynCompact")                 \
  X(ssbo, kSsboDynSegments,     "DECAL_SSBO_DYN_SEGMENTS",     28, "DynSegments")                \
  X(ssbo, kSsboDynCounters,     "DECAL_SSBO_DYN_COUNTERS",     29, "DynCounters")                \
  X(ssbo, kSsboLodSelection,    "DECAL_SSBO_LOD_SELECTION",    30, "LodSelection")               \
  X(ssbo, kSsboDynHeads,        "DECAL_SSBO_DYN_HEADS",        31, "DynHeads")                   \
  X(ssbo, kSsboDynNodes,        "DECAL_SSBO_DYN_NODES",        32, "DynNodes")                   \
  X(ssbo, kSsboLodPoints,       "DECAL_SSBO_LOD_POINTS",       33, "LodPoints")                  \
  X(ssbo, kSsboLodSegments,     "DECAL_SSBO_LOD_SEGMENTS",     34, "LodSegments")                \
  X(ssbo, kSsboLodMap,          "DECAL_SSBO_LOD_MAP",          35, "LodMap")                     \
  X(ssbo, kSsboLodLinks,        "DECAL_SSBO_LOD_LINKS",        36, "LodLinks")                   \
  X(ssbo, kSsboLodLineDrawn,    "DECAL_SSBO_LOD_LINE_DRAWN",   37, "LodLineDrawn")               \
  X(ssbo, kBindingDashTable,    "DECAL_SSBO_DASH_TABLE",       38, "DashTable")                  \
  X(ssbo, kBindingDashVertex,   "DECAL_SSBO_DASH_VERTEX",      39, "DashVertex")                 \
  X(ssbo, kSsboDynDash,         "DECAL_SSBO_DYN_DASH",         40, "DynDash")                    \
  X(ssbo, kSsboTerrainGradient, "DECAL_SSBO_TERRAIN_GRADIENT", 24, "B_terrain_gradient")         \
  X(unit, kUnitSlopeLayers,     "DECAL_UNIT_SLOPE_LAYERS",     24, "u_slope_layers")             \
  X(unit, kUnitUnlitLayers,     "DECAL_UNIT_UNLIT_LAYERS",     25, "u_unlit_layers")             \
  X(unit, kUnitTerrainGradient, "DECAL_UNIT_TERRAIN_GRADIENT", 26, "u_terrain_gradient")         \
  X(unit, kUnitDecalTexture,    "DECAL_UNIT_DECAL_TEXTURE",    27, "u_decal_texture")            \
  X(unit, kUnitMinWidths,       "DECAL_UNIT_MIN_WIDTHS",       27, "u_min_widths")               \
  X(unit, kUnitDynamicLayer,    "DECAL_UNIT_DYNAMIC_LAYER",    28, "u_dynamic")                  \
  X(unit, kUnitTerrainColour,   "DECAL_UNIT_TERRAIN_COLOUR",   29, "u_terrain")                  \
  X(unit, kUnitDecalLayer,      "DECAL_UNIT_DECAL_LAYER",      30, "u_decals")                   \
  X(unit, kUnitDepth,           "DECAL_UNIT_DEPTH",            31, "u_depth")                    \
  X(unit, kUnitDynMinWidths,    "DECAL_UNIT_DYN_MIN_WIDTHS",   32, "u_dyn_min_widths")           \
  X(unit, kUnitUnlitLayer,      "DECAL_UNIT_UNLIT_LAYER",      33, "u_unlit")
// clang-format on

#define DECAL_GL_FRAME_CONSTANT(kind, name, macro, index, resource) \
  inline constexpr uint32_t name = index;
DECAL_GL_FRAME_BINDINGS(DECAL_GL_FRAME_CONSTANT)
#undef DECAL_GL_FRAME_CONSTANT

inline constexpr uint32_t kBindingFrameFirst = 24;

enum class FrameKind : uint8_t { ssbo, unit };
struct FrameBinding {
  FrameKind kind;
  std::string_view macro;  // the GLSL #define of the index
  uint32_t index;
  std::string_view resource;  // the block or sampler uniform
};
inline constexpr FrameBinding kFrameBindings[] = {
#define DECAL_GL_FRAME_ROW(kind, name, macro, index, resource) \
  {FrameKind::kind, macro, name, resource},
    DECAL_GL_FRAME_BINDINGS(DECAL_GL_FRAME_ROW)
#undef DECAL_GL_FRAME_ROW
};

// How blobs are exposed to shaders.
enum class BindingMode { ssbo, texture };

}  // namespace decal::gl
