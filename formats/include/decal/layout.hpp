// decal/layout.hpp — conversions between the v1.0–1.2 and the v1.3 layouts
// of the per-cell ranges and the quad-tree leaf polygons (SPEC.md
// "Compact layout (v1.3)"). decalprep's build stage makes the v1.3 arrays
// (with Box16Encoder); the CPU view of a model or a package decodes them
// into the v1.2 arrays its evaluator walks; the GL loader encodes the blobs
// of older files, so that the shaders read one layout only.
//
// Inputs that have passed decal::validate_blobs (for the layout they are
// in) convert exactly. Others (a model in memory before the GL loader's
// check) give unspecified results, but no function reads or writes out of
// bounds. Depends on the standard library only; never throws
// (std::bad_alloc aside).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace decal::layout {

using u2 = std::array<uint32_t, 2>;
using u4 = std::array<uint32_t, 4>;

// Per-cell lists of one kind (static lines or polygons).
//
// v1.2: per cell (first, count) into the list blob (`cell_segment_range`,
// `cell_poly_range`) and (first node, leaf slots, internal nodes, 0) into the
// box blob (`line_bvh_range`, `poly_bvh_range`).
// v1.3: one `cell_*_first` element per cell plus one: (first list entry,
// first BVH node); cell c owns entries [first[c].x, first[c+1].x) and nodes
// [first[c].y, first[c+1].y), 2P - 1 of them for P leaf slots (0 when the
// cell is empty).
//
// Encodes the v1.2 ranges. When every cell's list and tree already follow
// the previous cell's (what decalprep writes), `list` and `boxes` are left
// empty and the caller keeps its own; else they receive the cell lists and
// trees copied in cell order (elements of `list_elem` and `box_elem` bytes
// taken from `list_src` / `box_src`). Cells whose list is empty keep no
// nodes. When no cell has an entry the kind is absent: `first` is empty
// (its blob is not written) and so are `list` and `boxes`.
struct CellEncoding {
  bool ok = true;  // false: the ranges break the v1.2 index constraints
  std::vector<u2> first;
  std::vector<std::byte> list, boxes;  // empty: the input's are already in order
};
CellEncoding encode_cells(std::span<const u2> range, std::span<const u4> bvh,
                          std::span<const std::byte> list_src, size_t list_elem,
                          std::span<const std::byte> box_src, size_t box_elem);
// Decodes v1.3 `cell_*_first` into the v1.2 ranges.
void decode_cells(std::span<const u2> first, std::vector<u2>& range, std::vector<u4>& bvh);

// Quad-tree leaf polygons.
//
// v1.2: per partial leaf (first, count) into `qt_leaf_segments`, each
// segment (start, end) into `qt_leaf_vertices`.
// v1.3: per partial leaf (first, count) into `qt_leaf_loops` (blob
// `qt_leaf_loop_range`); per loop one u32, one past its last vertex: loop l
// holds vertices [end[l-1], end[l]) (end[-1] = 0) and their edges v -> v + 1,
// the last one back to the loop's first vertex.
//
// Encodes leaf segments that are such loops (every file decalprep writes).
// Returns false, with the outputs unspecified, when a leaf's segments are not
// closed runs of consecutive vertices in increasing order (a hand-made v1.2
// file): such leaves cannot be expressed as loops.
bool encode_leaves(std::span<const u2> leaf_range, std::span<const u2> segments,
                   uint64_t vertex_count, std::vector<u2>& loop_range,
                   std::vector<uint32_t>& loop_end);
// Decodes v1.3 loops into the v1.2 leaf ranges and segments.
void decode_leaves(std::span<const u2> loop_range, std::span<const uint32_t> loop_end,
                   std::vector<u2>& leaf_range, std::vector<u2>& segments);

// Per-cell BVH boxes.
//
// v1.2: ivec4 (xmin, ymin, xmax, ymax) in quanta (`line_bvh_box`,
// `poly_bvh_box`); an empty node has xmin > xmax.
// v1.3: uvec2 (`line_bvh_box16`, `poly_bvh_box16`): x = xlo | ylo << 16,
// y = xhi | yhi << 16, u16 steps of 2^s quanta from the cell's base
// corner, the cell's lower-left corner minus one step on each axis. s is the
// smallest shift for which the cell and one step on each side fit in 65535
// steps (box16_shift). A box is stored clipped to that grown cell, its lower
// bounds rounded down and its upper bounds rounded up to whole steps:
// for every point of the cell (and within one step of it) the stored box
// answers "inside, or within m of it" exactly as the full box does when
// s = 0 (cells up to 65533 quanta), and conservatively otherwise. An empty
// node is xlo = 65535, xhi = 0 (xlo > xhi, as no stored box can have).
// The node's cell is the one whose [first[c].y, first[c+1].y) holds it.
struct CellGrid {
  int64_t origin_x = 0, origin_y = 0, cell_w = 1, cell_h = 1;
  uint32_t nx = 0;
};
uint32_t box16_shift(int64_t cell_w, int64_t cell_h);
// One box of a node of cell `cell`, encoded as encode_boxes16 encodes each
// element. Every bound is a monotone function of the box's bound, so the
// encoding of a union of boxes is the union (least lows, greatest highs) of
// their encodings (box16_union): a cell's tree can be built on encoded
// leaves, to the same bytes.
class Box16Encoder {
 public:
  static constexpr u2 kEmpty{65535u, 0u};  // an empty node
  explicit Box16Encoder(const CellGrid& grid);
  u2 operator()(uint64_t cell, const std::array<int32_t, 4>& box) const;

 private:
  CellGrid grid_;
  uint32_t shift_ = 0;
  int64_t top_x_ = 0, top_y_ = 0;  // the grown cell's size in steps
};
// The encoded box of the union of the boxes `a` and `b` encode (either may
// be Box16Encoder::kEmpty).
u2 box16_union(const u2& a, const u2& b);
std::vector<u2> encode_boxes16(std::span<const u2> first,
                               std::span<const std::array<int32_t, 4>> boxes, const CellGrid& grid);
std::vector<std::array<int32_t, 4>> decode_boxes16(std::span<const u2> first,
                                                   std::span<const u2> boxes, const CellGrid& grid);

// Exterior-polygon entries of the cells.
//
// v1.2: `cell_polys` uvec4 (polygon, culling node, first hole, hole count)
// into `cell_holes`.
// v1.3: `cell_poly_entries` uvec2 (polygon, culling node) and
// `cell_poly_holes`, one u32 per entry plus one: entry k's holes are
// `cell_holes[h[k], h[k+1])`.
//
// Encodes `cell_polys`. When the entries' holes already follow each other
// (what decalprep writes) `holes` is left empty; else it receives the hole
// entries copied in entry order. No entries: everything empty.
struct PolyEntryEncoding {
  bool ok = true;  // false: a hole range runs past `cell_holes`
  std::vector<u2> entries;
  std::vector<uint32_t> hole_first;
  std::vector<u2> holes;
};
PolyEntryEncoding encode_poly_entries(std::span<const u4> cell_polys,
                                      std::span<const u2> cell_holes);
void decode_poly_entries(std::span<const u2> entries, std::span<const uint32_t> hole_first,
                         std::vector<u4>& cell_polys);

// Leaf slots of a v1.3 cell tree of `nodes` nodes (2P - 1 -> P; 0 -> 0).
constexpr uint32_t leaf_slots_of(uint32_t nodes) {
  return nodes == 0 ? 0 : uint32_t((uint64_t(nodes) + 1) / 2);
}

}  // namespace decal::layout
