// decal/format.hpp — the one place that defines the .decals package format:
// magic, versions, file header, blob table entry, blob ids, element types and
// the std430 element structs. The writer (libprep/write), the reader
// (formats/src) and the GL loader (formats/gl) all include this header and
// nothing else defines these values. Normative text: formats/SPEC.md.
//
// Depends on the C++ standard library only.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace decal {

// ---------------------------------------------------------------------------
// Coordinates (ARCHITECTURE.md "Precision"). Every stored position is a signed 32-bit
// integer count of `kQuantumMetres` relative to the package origin (metadata
// `origin`), so any point within ±2147 km of the origin is held to 0.5 mm.
// No absolute float32 coordinate is ever stored.
// ---------------------------------------------------------------------------
inline constexpr double kQuantumMetres = 0.001;

// ---------------------------------------------------------------------------
// Element types of a blob. Numbering is part of the format; never reuse.
// ---------------------------------------------------------------------------
enum class ElementType : uint32_t {
  u8 = 1,
  u32 = 2,
  i32 = 3,
  f32 = 4,
  ivec2 = 5,    // int32[2], std430 stride 8
  uvec2 = 6,    // uint32[2], stride 8
  ivec4 = 7,    // int32[4], stride 16
  uvec4 = 8,    // uint32[4], stride 16
  vec2 = 9,     // float[2], stride 8
  vec4 = 10,    // float[4], stride 16
  record = 11,  // a fixed struct described in SPEC.md for that blob id
};

// std430 stride of plain element types; 0 for `record` (the blob id's
// struct gives it).
constexpr uint32_t std430_stride(ElementType t) {
  switch (t) {
    case ElementType::u8: return 1;
    case ElementType::u32:
    case ElementType::i32:
    case ElementType::f32: return 4;
    case ElementType::ivec2:
    case ElementType::uvec2:
    case ElementType::vec2: return 8;
    case ElementType::ivec4:
    case ElementType::uvec4:
    case ElementType::vec4: return 16;
    case ElementType::record: return 0;
  }
  return 0;
}

// ---------------------------------------------------------------------------
// Blob catalogue. The numeric id is what the blob table stores; the name is
// informative (also stored). Readers skip ids they do not know. The table in
// SPEC.md §"Blob catalogue" lists exactly these rows (a test checks it).
//
// Index conventions: "cell" = grid cell index ix + nx*iy; all "range" blobs
// hold (first, count) into the list blob that follows them.
// ---------------------------------------------------------------------------
enum class BlobId : uint32_t {
  // --- static lines (thesis §4.2.1 "Line Segments") ---
  line_vertices = 1,       // ivec2  per vertex: position, quanta from origin
  line_vertex_line = 2,    // u32    per vertex: index of its line
  line_props = 3,          // record LineProps per line
  line_corners = 4,        // record LineCorner per vertex (miter + 2 bevel vectors)
  cell_segment_range = 5,  // uvec2  per cell: (first, count) into cell_segments
  cell_segments = 6,       // uvec2  per (cell, segment): (start vertex, end vertex),
                           //        sorted by the line's drawing order, then segment
  cell_line_first = 7,     // uvec2  v1.3, per cell plus one: (first entry in cell_segments,
                           //        first node in line_bvh_box16); replaces ids 5 and 20
  // --- static polygons (thesis §4.2.1 "Polygon Quad-Trees") ---
  poly_props = 10,        // record PolyProps per polygon (exterior and interior)
  poly_root_node = 11,    // u32    per polygon: index of its root quad-tree node
  qt_node_box = 12,       // ivec4  per node: (xmin, ymin, xmax, ymax) quanta
  qt_node = 13,           // ivec2  per node: (type 0..3, offset), see QtNodeType
  qt_leaf_range = 14,     // uvec2  per partial leaf: (first, count) into qt_leaf_segments
  qt_leaf_segments = 15,  // uvec2  per leaf-polygon segment: (start, end) into qt_leaf_vertices
  qt_leaf_vertices = 16,  // ivec2  per leaf-polygon vertex, quanta. Leaf polygons are the
                          //        unclipped ring edges meeting the node box plus closing
                          //        segments outside it (vertices may lie outside the box);
                          //        even-odd is exact only for points inside the box.
  cell_poly_range = 17,   // uvec2  per cell: (first, count) into cell_polys
  cell_polys = 18,        // uvec4  per (cell, exterior polygon): (polygon, culling node,
                          //        first hole entry, hole count) — holes index cell_holes
  cell_holes = 19,        // uvec2  per (cell, interior polygon): (polygon, culling node)
  // --- v1.3 compact layout (SPEC.md "Compact layout (v1.3)"; decal/layout.hpp) ---
  qt_leaf_loop_range = 24,  // uvec2  per partial leaf: (first, count) into qt_leaf_loops
  qt_leaf_loops = 25,       // u32    per leaf loop: one past its last vertex in qt_leaf_vertices;
                            //        it starts where the previous loop ends (replaces 14, 15)
  cell_poly_first = 26,  // uvec2  per cell plus one: (first entry in cell_poly_entries, first node
                         //        in poly_bvh_box16); replaces ids 17 and 22
  line_bvh_box16 = 27,   // uvec2  per line-BVH node: cell-relative u16 box (replaces 21)
  poly_bvh_box16 = 28,   // uvec2  per polygon-BVH node: as line_bvh_box16 (replaces 23)
  cell_poly_entries = 29,  // uvec2  per (cell, exterior polygon): (polygon, culling node)
  cell_poly_holes = 9,     // u32    per cell_poly_entries entry plus one: first entry in
                           //        cell_holes (29 and 9 replace 18)
  // --- per-cell BVHs (thesis §4.2.1 "Bounding Volume Hierarchies") ---
  line_bvh_range = 20,  // uvec4  per cell: (first node, leaf slots, internal nodes, 0)
  line_bvh_box = 21,    // ivec4  per node: box in quanta; empty node: xmin > xmax
  poly_bvh_range = 22,  // uvec4  per cell, as line_bvh_range
  poly_bvh_box = 23,    // ivec4  per node, as line_bvh_box
  // --- dynamic lines (thesis §4.2.2 "Terrain Matching") ---
  dyn_vertices = 30,    // ivec4  per 3D vertex: (x, y, z quanta, line index)
  dyn_prev_next = 31,   // ivec2  per vertex: (previous, next) vertex, -1 at open ends
  dyn_line_start = 32,  // u32    per dynamic line: index of its first vertex
  dyn_line_props = 33,  // record LineProps per dynamic line (width in pixels)
  // --- LOD segments (LOCALIS, seed 001) ---
  lod_points = 40,      // record LodPoint per point
  lod_segments = 41,    // record LodSegment per attributed segment
  lod_line_range = 42,  // uvec2  per LOD line: (first, count) into lod_segments
  // --- provenance ---
  manifest_entries = 50,  // u8     UTF-8 JSON array: one object per repaired,
                          //        dropped or clipped-away feature (SPEC §Metadata)
};

struct BlobInfo {
  BlobId id;
  std::string_view name;
  ElementType type;
  uint32_t stride;  // std430 bytes per element
};

// ---------------------------------------------------------------------------
// Element structs (std430 layouts; static_asserts pin them).
// ---------------------------------------------------------------------------

enum class CornerStyle : uint32_t { round = 0, miter = 1, bevel = 2 };
enum class OutlineMode : uint32_t { normal = 0, inset = 1, offset = 2 };

// Bit layout of LineProps::style.
//   bits 0-1  CornerStyle
//   bits 2-3  OutlineMode (inset keeps the left side of the directed segment,
//             which is the polygon interior for CCW shells and CW holes)
//   bit  4    closed ring (no line ends)
//   bit  5    clipped to its ring (v1.1): LineProps::clip_node is the root of
//             the ring's own quad-tree, and a point counts as covered only if
//             it lies in the line's two-sided band AND the even-odd query of
//             that quad-tree equals bit 6 (the exact outline test; see the
//             comment block of libprep/evaluate/evaluate.cpp, step 6)
//   bit  6    with bit 5: the kept half is the ring's inside (inset of a CCW
//             ring, offset of a CW ring); clear: its outside
//   bits 7-31 zero
inline constexpr uint32_t kStyleCornerMask = 0x3u;
inline constexpr uint32_t kStyleOutlineShift = 2;
inline constexpr uint32_t kStyleOutlineMask = 0x3u << kStyleOutlineShift;
inline constexpr uint32_t kStyleClosedBit = 1u << 4;
inline constexpr uint32_t kStyleClipBit = 1u << 5;
inline constexpr uint32_t kStyleClipInsideBit = 1u << 6;

// A static line's half width is in [0, kMaxHalfWidthMetres) (SPEC.md "Index
// constraints"): half the equator's length, so no real stroke reaches it,
// and well inside the int32 millimetre range a package's positions use.
inline constexpr float kMaxHalfWidthMetres = 1e7f;

struct LineProps {
  float half_width;    // metres for static lines (already doubled for inset/offset);
                       // pixels for dynamic lines
  uint32_t rgba;       // colour, R in the low byte, straight (non-premultiplied) alpha
  uint32_t order;      // drawing-order rank, 0 = drawn on top; unique per line
  uint32_t style;      // see kStyle* bits
  float value;         // attribute value for colour ramps (NaN when none)
  uint32_t layer;      // index into metadata `layers`
  uint32_t feature;    // index into metadata provenance (source feature)
  uint32_t clip_node;  // with kStyleClipBit: root node (qt_node index) of the
                       // quad-tree of the line's own ring, a quad-tree that
                       // no polygon and no cell refers to; else zero (v1.0:
                       // `reserved`, zero). Always zero in dyn_line_props.
};
static_assert(sizeof(LineProps) == 32);

// Thesis §3.6 / §4.2.1: per vertex, the miter vector (from the vertex to the
// left miter corner, length = half width / sin(θ/2)); a null miter marks a
// round end or a round fallback (< 40° between segments). The two bevel
// vectors point from the vertex to the outer corners of the incoming and
// outgoing segment rectangles, on the outer side of the turn. Metres.
// Precisely (libprep/model/lines.cpp): bevel_in / bevel_out = half width x
// the unit normal of the incoming / outgoing segment, both on the outer side
// of the turn (CGAL orientation; the left side where the turn is straight and
// at open ends), null where that segment does not exist (open line ends).
// They are stored for every corner style: a miter segment uses them at its
// null-miter ends, and inset/offset use them to clip by the neighbouring
// segment. The exact per-segment test is the comment block at the top of
// libprep/evaluate/evaluate.cpp.
struct LineCorner {
  float miter[2];
  float bevel_in[2];
  float bevel_out[2];
};
static_assert(sizeof(LineCorner) == 24);

struct PolyProps {
  uint32_t rgba;     // colour (interior polygons: 0)
  uint32_t order;    // drawing-order rank among exterior polygons, 0 = top
  int32_t exterior;  // interior polygons: index of their exterior; exterior: -1
  float value;       // attribute value for colour ramps (NaN when none)
  uint32_t layer;
  uint32_t feature;
  uint32_t reserved[2];  // must be zero
};
static_assert(sizeof(PolyProps) == 32);

// Thesis §4.2.1 node types.
enum class QtNodeType : int32_t {
  internal = 0,  // offset = index of the first of 4 consecutive children (SW, SE, NW, NE)
  outside = 1,   // fully outside leaf; offset = 0
  inside = 2,    // fully inside leaf; offset = 0
  partial = 3,   // offset = index into qt_leaf_range
};

// ---------------------------------------------------------------------------
// LOD segments (LOCALIS, seed 001 §3.1-3.5). Normative text for SPEC.md.
//
// Every LOD line (a dynamic line of a layer with `lod = true`) is turned
// into a Douglas-Peucker BLG-tree and then into its exhaustive set of
// attributed segments: every segment that can appear in any simplification
// (rules 1-3 of §3.2: 2n-1 segments for a line of n segments). A closed
// outline is stored with its first point repeated as its last point.
//
// Point inclusion. For a camera at C = (cx, cy, cz) in scene metres
// relative to the package origin, let d(p) = |(eval_x, eval_y) * quantum -
// (cx, cy)| combined with cz: d = sqrt(dx^2 + dy^2 + cz^2) (any distance
// that changes by at most |p - q| between two points works). Given a
// non-decreasing threshold function eps(d) (metres; the screen-space error
// threshold), a point p is INCLUDED iff
//     (flags & kLodPointAlways) != 0   or   e_star > eps(d(p) - d_star)
// which is LOCALIS Eq. (7) with the pre-evaluated e* and d*.
//
// Segment visibility (Eq. (2)/(4)). A segment is VISIBLE iff
//     (generator == kLodNone or generator is INCLUDED) and
//     (splitter  == kLodNone or splitter  is NOT INCLUDED).
// For every camera and every non-decreasing eps the visible segments of a
// line form one connected polyline from its first to its last point. For a
// constant eps (and a package built without dependees) they are exactly the
// Douglas-Peucker simplification of the line at tolerance eps (distance of a
// point to the baseline SEGMENT; ties go to the first point).
//
// How e*, d* are made (informative): e0 = DP error of the point, made
// non-increasing down the BLG-tree (min with the parent's: a node is never
// kept when DP would stop above it). Edges s -> j mean "j included implies s
// included": s -> its BLG children (saturation, §3.3) and s -> each dependee
// (§3.4: a point of any LOD line lying inside the closed polygon of the
// original sub-line that s's baseline replaces). Strongly connected
// components (cycles) are merged into one proxy: mean position (eval_x,
// eval_y), maximum attributes. Over the condensed DAG
//     e*(X) = max(e0(X), e*(Y))   d*(X) = max(r(X), |X - Y| + d*(Y))
// for all edges X -> Y, r(X) = proxy radius. Points that depend on a line's
// end point (always drawn) get kLodPointAlways. Values are rounded up to
// float with a 1 mm margin per edge so the implications hold on the stored
// floats.
// ---------------------------------------------------------------------------
inline constexpr uint32_t kLodNone = 0xffffffffu;
inline constexpr uint32_t kLodPointAlways = 1u;  // LodPoint::flags bit 0

struct LodPoint {
  int32_t x, y;            // drawing position, quanta
  int32_t eval_x, eval_y;  // position for the camera distance d (the proxy
                           // centroid for points merged from a cycle), quanta
  float e_star;            // pre-evaluated error e* (Eq. 7), metres
  float d_star;            // pre-evaluated distance d* (Eq. 7), metres
  uint32_t line;           // index of its dynamic line (dyn_line_props)
  uint32_t flags;          // bit 0 kLodPointAlways; other bits must be zero
};
static_assert(sizeof(LodPoint) == 32);

struct LodSegment {
  uint32_t a, b;       // point indices (lod_points), a before b along the line
  uint32_t generator;  // point whose inclusion creates the segment (a or b),
                       // kLodNone for the line's base segment (first, last)
  uint32_t splitter;   // point whose inclusion splits it, kLodNone for an
                       // original segment of the line
};
static_assert(sizeof(LodSegment) == 16);

// The plain element types and their C++ types (std430 layouts):
// X(ElementType, C++ type).
// clang-format off
#define DECAL_ELEMENT_TYPES(X) \
  X(u8, uint8_t) X(u32, uint32_t) X(i32, int32_t) X(f32, float) \
  X(ivec2, std::array<int32_t, 2>) X(uvec2, std::array<uint32_t, 2>) \
  X(ivec4, std::array<int32_t, 4>) X(uvec4, std::array<uint32_t, 4>) \
  X(vec2, std::array<float, 2>) X(vec4, std::array<float, 4>)
// clang-format on

// element::ivec2 etc.: the C++ type of a plain element type.
namespace element {
#define DECAL_ELEMENT_ALIAS(tag, ...) using tag = __VA_ARGS__;
DECAL_ELEMENT_TYPES(DECAL_ELEMENT_ALIAS)
#undef DECAL_ELEMENT_ALIAS
}  // namespace element

// The element type tag of a C++ element type: a plain type above, else a
// record (an element struct).
template <class T>
inline constexpr ElementType element_type_of = ElementType::record;
#define DECAL_ELEMENT_TAG(tag, ...) \
  template <>                       \
  inline constexpr ElementType element_type_of<element::tag> = ElementType::tag;
DECAL_ELEMENT_TYPES(DECAL_ELEMENT_TAG)
#undef DECAL_ELEMENT_TAG

// The blob catalogue, the one list of the blobs this build knows, in
// catalogue order: X(id, C++ element type). The catalogue rows (name,
// element type tag, stride) and BlobTraits below are made from it.
// clang-format off
#define DECAL_BLOB_CATALOGUE(X) \
  X(line_vertices, element::ivec2)      \
  X(line_vertex_line, element::u32)     \
  X(line_props, LineProps)              \
  X(line_corners, LineCorner)           \
  X(cell_segment_range, element::uvec2) \
  X(cell_segments, element::uvec2)      \
  X(cell_line_first, element::uvec2)    \
  X(poly_props, PolyProps)              \
  X(poly_root_node, element::u32)       \
  X(qt_node_box, element::ivec4)        \
  X(qt_node, element::ivec2)            \
  X(qt_leaf_range, element::uvec2)      \
  X(qt_leaf_segments, element::uvec2)   \
  X(qt_leaf_vertices, element::ivec2)   \
  X(cell_poly_range, element::uvec2)    \
  X(cell_polys, element::uvec4)         \
  X(cell_holes, element::uvec2)         \
  X(line_bvh_range, element::uvec4)     \
  X(line_bvh_box, element::ivec4)       \
  X(poly_bvh_range, element::uvec4)     \
  X(poly_bvh_box, element::ivec4)       \
  X(qt_leaf_loop_range, element::uvec2) \
  X(qt_leaf_loops, element::u32)        \
  X(cell_poly_first, element::uvec2)    \
  X(line_bvh_box16, element::uvec2)     \
  X(poly_bvh_box16, element::uvec2)     \
  X(cell_poly_entries, element::uvec2)  \
  X(cell_poly_holes, element::u32)      \
  X(dyn_vertices, element::ivec4)       \
  X(dyn_prev_next, element::ivec2)      \
  X(dyn_line_start, element::u32)       \
  X(dyn_line_props, LineProps)          \
  X(lod_points, LodPoint)               \
  X(lod_segments, LodSegment)           \
  X(lod_line_range, element::uvec2)     \
  X(manifest_entries, element::u8)
// clang-format on

inline constexpr BlobInfo kBlobCatalogue[] = {
#define DECAL_BLOB_INFO(id, T) {BlobId::id, #id, element_type_of<T>, uint32_t(sizeof(T))},
    DECAL_BLOB_CATALOGUE(DECAL_BLOB_INFO)
#undef DECAL_BLOB_INFO
};

// BlobTraits<id>::type: the element type of blob `id` (undefined for an id
// not in the catalogue), e.g. decal::Package::array<id>() returns a span of it.
template <BlobId id>
struct BlobTraits;
#define DECAL_BLOB_TRAITS(id, T)  \
  template <>                     \
  struct BlobTraits<BlobId::id> { \
    using type = T;               \
  };
DECAL_BLOB_CATALOGUE(DECAL_BLOB_TRAITS)
#undef DECAL_BLOB_TRAITS

// A plain element type's C++ type has its std430 stride.
constexpr bool catalogue_strides_match() {
  for (const auto& b : kBlobCatalogue)
    if (b.type != ElementType::record && b.stride != std430_stride(b.type)) return false;
  return true;
}
static_assert(catalogue_strides_match());

// Blobs of the v1.0–1.2 layout that v1.3 replaced (SPEC.md "Compact layout
// (v1.3)"): readers still read them in older files; writers of v1.3 do not
// write them.
inline constexpr BlobId kSupersededBlobs[] = {
    BlobId::cell_segment_range, BlobId::qt_leaf_range,  BlobId::qt_leaf_segments,
    BlobId::cell_poly_range,    BlobId::line_bvh_range, BlobId::line_bvh_box,
    BlobId::poly_bvh_range,     BlobId::poly_bvh_box,   BlobId::cell_polys};
constexpr bool is_superseded(BlobId id) {
  for (BlobId s : kSupersededBlobs)
    if (s == id) return true;
  return false;
}

// Returns the catalogue row of `id`, or nullptr for an id this build does not
// know (readers must skip such blobs).
constexpr const BlobInfo* find_blob_info(BlobId id) {
  for (const auto& b : kBlobCatalogue)
    if (b.id == id) return &b;
  return nullptr;
}

// ---------------------------------------------------------------------------
// File-level structures (SPEC.md §"File structure"). All integers are
// little-endian; these structs mirror the on-disk bytes exactly on the
// little-endian hosts this project targets (static_asserts pin the layout).
//
//   [FileHeader 96 B][BlobTableEntry 96 B x blob_count][metadata JSON]
//   [zero padding to 256][blob 0][zero padding to 256][blob 1]...[blob n-1]
// ---------------------------------------------------------------------------

// Magic, PNG-style: the high-bit first byte catches 7-bit transports and
// tells the file from text, "DCL" names it in a hex dump, CR LF catches
// line-ending conversion, 0x1A stops DOS `type`, the final LF catches
// LF -> CRLF conversion.
inline constexpr unsigned char kMagic[8] = {0x89, 'D', 'C', 'L', '\r', '\n', 0x1A, '\n'};

// Version policy (SPEC.md §"Versioning"): a reader rejects any major
// version other than its own, naming the version; it reads any minor
// version of its major (newer minors only add optional things).
inline constexpr uint16_t kVersionMajor = 1;
inline constexpr uint16_t kVersionMinor = 3;

// Flags. Bits 0-15 are "required": a reader rejects a file with a required
// bit it does not know. Bits 16-31 are "optional": unknown ones are ignored.
inline constexpr uint32_t kRequiredFlagsMask = 0x0000FFFFu;
inline constexpr uint32_t kKnownRequiredFlags = 0;  // none in v1.x
// Every blob is stored with codec none, so the whole package can be mapped.
inline constexpr uint32_t kFlagAllUncompressed = 1u << 16;
inline constexpr uint32_t kKnownOptionalFlags = kFlagAllUncompressed;

// The largest metadata chunk a reader accepts (SPEC.md "Metadata"), refused
// before it is parsed: a JSON DOM takes about 25 times its text, and the
// metadata decalprep writes is a few kB per layer (the manifest entries
// are a blob).
inline constexpr uint64_t kMaxMetadataBytes = uint64_t(16) << 20;

// Every blob starts at a multiple of this many bytes from the file start;
// the bytes between regions are zero.
inline constexpr uint64_t kBlobAlignment = 256;

// Codec of a stored blob. Numbering is part of the format.
enum class CodecId : uint32_t {
  none = 0,  // stored bytes are the raw bytes
  zstd = 1,  // one zstd frame (RFC 8878) with the content size field set
};

inline constexpr size_t kBlobNameSize = 32;

struct FileHeader {
  unsigned char magic[8];      // kMagic
  uint16_t version_major;      // kVersionMajor
  uint16_t version_minor;      // kVersionMinor
  uint32_t flags;              // kFlag* bits
  uint32_t header_size;        // sizeof(FileHeader) = 96 in v1
  uint32_t blob_entry_size;    // sizeof(BlobTableEntry) = 96 in v1
  uint32_t blob_count;         // entries in the blob table
  uint32_t reserved0;          // must be zero
  uint64_t file_size;          // total bytes in the file
  uint64_t table_offset;       // = header_size
  uint64_t table_checksum;     // XXH64(seed 0) of the whole blob table
  uint64_t metadata_offset;    // = table_offset + blob_count * blob_entry_size
  uint64_t metadata_size;      // bytes of UTF-8 JSON, no terminator
  uint64_t metadata_checksum;  // XXH64(seed 0) of the metadata bytes
  uint64_t reserved1;          // must be zero
  uint64_t header_checksum;    // XXH64(seed 0) of header bytes [0, header_size - 8)
};
static_assert(sizeof(FileHeader) == 96);
static_assert(offsetof(FileHeader, version_major) == 8);
static_assert(offsetof(FileHeader, file_size) == 32);
static_assert(offsetof(FileHeader, header_checksum) == 88);

struct BlobTableEntry {
  uint32_t id;               // BlobId value
  uint32_t element_type;     // ElementType value
  uint32_t stride;           // std430 bytes per element
  uint32_t codec;            // CodecId value
  uint64_t count;            // elements; raw_size = count * stride
  uint64_t offset;           // from file start; multiple of kBlobAlignment
  uint64_t stored_size;      // bytes in the file
  uint64_t raw_size;         // bytes after decoding
  uint64_t checksum;         // XXH64(seed 0) of the stored bytes
  char name[kBlobNameSize];  // [a-z0-9_]+, NUL-padded; catalogue name for known ids
  uint32_t reserved[2];      // must be zero
};
static_assert(sizeof(BlobTableEntry) == 96);
static_assert(offsetof(BlobTableEntry, count) == 16);
static_assert(offsetof(BlobTableEntry, checksum) == 48);
static_assert(offsetof(BlobTableEntry, name) == 56);

// The name of an element type as SPEC.md writes it ("ivec2"), or "" when
// unknown.
constexpr std::string_view element_type_name(ElementType t) {
  switch (t) {
    case ElementType::u8: return "u8";
    case ElementType::u32: return "u32";
    case ElementType::i32: return "i32";
    case ElementType::f32: return "f32";
    case ElementType::ivec2: return "ivec2";
    case ElementType::uvec2: return "uvec2";
    case ElementType::ivec4: return "ivec4";
    case ElementType::uvec4: return "uvec4";
    case ElementType::vec2: return "vec2";
    case ElementType::vec4: return "vec4";
    case ElementType::record: return "record";
  }
  return "";
}

}  // namespace decal
