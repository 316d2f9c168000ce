// libprep/model/detail.hpp — internals of the build stage (static decals).
// Not a public header: only libprep/model/*.cpp include it. No CGAL here.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <decal/layout.hpp>

#include "prep/features.hpp"
#include "prep/model.hpp"

namespace prep::detail {

// An integer position in quanta relative to the package origin (int64 so
// that sums and doubled coordinates never overflow).
struct QPoint {
  int64_t x = 0, y = 0;
  bool operator==(const QPoint&) const = default;
};

// Closed integer rectangle [x0, x1] x [y0, y1] in quanta.
struct QBox {
  int64_t x0 = 0, y0 = 0, x1 = -1, y1 = -1;
  bool empty() const { return x0 > x1 || y0 > y1; }
};

// Largest |coordinate| in quanta that a stored position may have: one
// quantum is kept free so the quad-tree closing frame (root box + 1) still
// fits in int32.
inline constexpr int64_t kMaxQuanta = 2147483647LL - 2;

// Quantises a point given in metres relative to the origin (llround to the
// 1 mm quantum). Updates `max_err` with the Euclidean representation error
// in metres. Throws resource_error (message built from `where`) when the
// point is not finite or lies more than ~2147 km from the origin.
// `where` names the feature in an error; it is called only when `p` cannot
// be quantised (not finite, or beyond kMaxQuanta), so a vertex that can costs
// no message.
using WhereFn = std::function<std::string()>;
QPoint quantise(const Point2& p, double& max_err, const WhereFn& where);

// ------------------------------------------------------------- quad-tree --

// One polygon's quad-tree (thesis §4.2.1 "Polygon Quad-Trees"), with indices
// local to this tree: node children, leaf ranges and leaf segments index the
// vectors of this struct; build_model() rebases them when concatenating.
struct PolyQuadTree {
  std::vector<ivec4> box;            // per node
  std::vector<ivec2> node;           // per node: (QtNodeType, offset)
  std::vector<uvec2> leaf_range;     // per partial leaf: (first, count) into leaf_loops
  std::vector<uint32_t> leaf_loops;  // per loop: one past its last vertex (DecalModel)
  std::vector<ivec2> leaf_vertices;
  uint32_t depth_capped = 0;       // leaves that stopped at max depth with > capacity segments
  uint32_t max_leaf_segments = 0;  // ring segments in the fullest leaf
};

// Working arrays of build_quadtree, kept between calls (one per thread) so
// that a tree costs no allocation once they have grown.
struct QtPoint2 {  // doubled integer coordinates (|v| < 2^33): box centres are integers
  int64_t px = 0, py = 0;
  int64_t x() const { return px; }
  int64_t y() const { return py; }
};
struct QtWork {  // a node to split or close
  QBox box;
  uint32_t first = 0,
           count = 0;   // its ring edges (i, i+1): [first, first+count) of the level's list
  uint32_t id = 0;      // node index
  bool parity = false;  // inside at the box centre (evaluator rule, exact)
};
struct QuadTreeScratch {
  std::vector<QtPoint2> doubled;
  std::vector<QtWork> level, next_level;
  std::vector<uint32_t> edges, next_edges;
  std::array<std::vector<uint32_t>, 4> child_edges;
};

// Builds the quad-tree of one closed ring (no repeated closing vertex, at
// least 3 vertices, every |coordinate| <= kMaxQuanta) into `t` (cleared
// first). Thread-safe with a scratch per thread.
void build_quadtree(const std::vector<QPoint>& ring, uint32_t leaf_capacity, uint32_t max_depth,
                    PolyQuadTree& t, QuadTreeScratch& scratch);
PolyQuadTree build_quadtree(const std::vector<QPoint>& ring, uint32_t leaf_capacity,
                            uint32_t max_depth);

// ----------------------------------------------------------------- lines --

// The conservative coverage shape of one widened segment, in quanta (double):
// the union of up to four triangles and, when `capsule`, the capsule of radius
// `hw` around a-b. Every point the evaluator counts as covered by the segment
// lies inside it.
struct SegmentShape {
  double ax = 0, ay = 0, bx = 0, by = 0;
  double hw = 0;  // half width, quanta
  bool capsule = false;
  int ntri = 0;
  std::array<std::array<double, 6>, 4> tri{};  // (x0,y0,x1,y1,x2,y2)
  QBox box;                                    // integer AABB of the shape (conservative)
  // The AABB of the line's shape at its stored width: the BVH leaf box (a
  // min_width_px line's wider shape registers it in more cells; readers
  // grow leaf boxes by the reach the pixel allows, formats/SPEC.md
  // "Minimum widths"). The same as `box` otherwise.
  QBox leaf_box;
  uint32_t line = 0;            // line index
  uint32_t start = 0, end = 0;  // vertex indices
};

// Lines converted to package arrays (line_vertices, line_vertex_line,
// line_props without `order`, line_corners) plus one shape per segment.
// Sort keys for the drawing order are returned per line.
//
// Drawing order (formats/SPEC.md "Drawing order"): static lines and exterior
// polygons share one rank space, rank 0 drawn on top. A later scene layer is
// above an earlier one; within a layer its lines are above its polygons
// (a layer's outlines over its own fill); within a layer and kind the
// importance attribute, else length or area, larger on top (thesis §4.2.1);
// then feature id, part and input index, so the order is total.
enum class DrawKind : uint8_t { line = 0, polygon = 1 };
struct DrawKey {
  double primary;  // importance, else length (lines) or area (polygons)
  uint32_t layer;  // scene layer index (file order)
  DrawKind kind;
  int64_t fid;
  int part;
  uint32_t input;  // index among the items of this kind
};
void build_lines(const SceneFeatures& scene, const ModelOptions& options, DecalModel& model,
                 std::vector<SegmentShape>& shapes, std::vector<DrawKey>& keys);

// Rank per key (0 = drawn on top) under the drawing order above.
std::vector<uint32_t> draw_ranks(const std::vector<DrawKey>& keys);

// ------------------------------------------------------------------ grid --

// What choose_grid() looks at. Pointers are borrowed for the call.
struct GridInput {
  QBox extent;                                        // of every static primitive, quanta
  const std::vector<SegmentShape>* shapes = nullptr;  // every static segment
  const std::vector<std::vector<uint32_t>>* ring_leaves = nullptr;  // solid leaf nodes per ring
  const std::vector<ivec4>* node_box = nullptr;                     // quad-tree node boxes
  const std::vector<uint8_t>* ring_is_hole = nullptr;               // per ring
  uint64_t geometry_bytes = 0;  // static blobs that do not depend on the grid
};

// Chooses the decal grid over input.extent: fixed nx x ny when both options
// are non-zero (500x500 = thesis §4.2.1), else adaptive and size-aware (rule
// documented at choose_grid in grid.cpp): square cells chosen by an explicit
// cost, log(1 + query-cost proxy) + 0.1 log(package bytes), where the bytes
// of each candidate's cell lists and per-cell BVHs are counted from the
// cells the segments and quad-tree leaves will be assigned to (exactly, or
// on a row sample for large inputs with the choice confirmed exactly);
// packages over kGridSizeBudget times the thesis 500x500 grid's on the same
// data are refused, as are grids over options.max_cells. Deterministic
// (integer counts). bench/bench_build compares it with 500x500. Throws resource_error
// when no grid fits.
// `cell_bytes`, when given, receives the chosen grid's per-cell bytes in
// that count (without input.geometry_bytes): exact, but for a choice made on
// samples when there is no size budget to confirm it against.
GridParams choose_grid(const GridInput& input, const ModelOptions& options,
                       double* cell_bytes = nullptr);

// The adaptive grid's package never exceeds this factor times the package
// the thesis 500x500 grid gives on the same data (grid.cpp).
inline constexpr double kGridSizeBudget = 1.2;

// Calls fn(cell_index) for every cell whose closed box, expanded by one
// quantum, meets `shape` (conservatively). Cells are visited in increasing
// row, then column.
template <class Fn>
void for_each_cell(const GridParams& g, const SegmentShape& shape, Fn&& fn);

// for_each_cell() restricted to the rows row0 <= iy <= row1 (choose_grid()
// counts a grid row by row).
template <class Fn>
void for_each_cell_in_rows(const GridParams& g, const SegmentShape& shape, int64_t row0,
                           int64_t row1, Fn&& fn);

// The inclusive cell index range overlapped by box `b` expanded by one
// quantum, clamped to the grid; returns false when outside the grid.
inline bool cell_range(const GridParams& g, const QBox& b, int64_t& ix0, int64_t& iy0, int64_t& ix1,
                       int64_t& iy1);

// Closed box of cell (ix, iy).
inline QBox cell_box(const GridParams& g, int64_t ix, int64_t iy) {
  QBox b;
  b.x0 = g.origin_x + ix * g.cell_w;
  b.y0 = g.origin_y + iy * g.cell_h;
  b.x1 = b.x0 + g.cell_w;
  b.y1 = b.y0 + g.cell_h;
  return b;
}

// The grid as the v1.3 box encoding sees it.
inline decal::layout::CellGrid cell_grid(const GridParams& g) {
  return {g.origin_x, g.origin_y, g.cell_w, g.cell_h, g.nx};
}

// ------------------------------------------------------------------- bvh --

// Builds per-cell implicit full binary BVHs (thesis §4.2.1 "Bounding Volume
// Hierarchies") in the v1.3 layout (formats/SPEC.md "Compact layout
// (v1.3)"): cell c's leaves are entries [first[c], first[c+1]) of its list,
// whose boxes, in the u16 form of decal::layout::Box16Encoder,
// leaf_boxes(c, first[c], n, out) writes to out[0, n). Fills cell_first (per
// cell plus one: first entry, first node) and the nodes' boxes.
using LeafBoxes = std::function<void(uint64_t cell, uint32_t first, uint32_t n, uvec2* out)>;
void build_bvhs(const std::vector<uint32_t>& first, const LeafBoxes& leaf_boxes,
                std::vector<uvec2>& cell_first, std::vector<uvec2>& boxes);

}  // namespace prep::detail

#include "grid_inl.hpp"
