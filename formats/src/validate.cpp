// validate.cpp — the one structural check of decoded blobs (SPEC.md "Index
// constraints"), for `verify`, the CPU evaluator and the GL loader alike. A
// package that passes can be traversed by the shaders (thesis §4.2.1) and
// the evaluator without any out-of-range read and without an endless loop:
// every index lies inside the blob it indexes, every (first, count) range
// inside its list, quad-tree children come after their parent, and the
// per-cell BVHs are full binary trees over their list. With a grid, the
// per-cell blobs must also hold one element per cell.
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "decal/inspect.hpp"
#include "decal/layout.hpp"
#include "message.hpp"

namespace decal {
namespace {

using u2 = std::array<uint32_t, 2>;
using u4 = std::array<uint32_t, 4>;
using i2 = std::array<int32_t, 2>;
using i4 = std::array<int32_t, 4>;
using ull = unsigned long long;

using detail::fmt;

// Elements of one blob, read with memcpy (blob bytes need not be aligned
// for T when they come from a caller's buffer).
template <class T>
struct Elements {
  const std::byte* p = nullptr;
  uint64_t n = 0;
  T operator[](uint64_t i) const {
    T v;
    std::memcpy(&v, p + i * sizeof(T), sizeof(T));
    return v;
  }
  uint64_t size() const { return n; }
};

class Checker {
 public:
  Checker(std::span<const BlobBytes> blobs, const ValidateOptions& o) : blobs_(blobs), opt_(o) {}

  // Sizes against the catalogue; each known id at most once.
  Status index_blobs() {
    for (const BlobBytes& b : blobs_) {
      const BlobInfo* info = find_blob_info(b.id);
      if (!info) continue;
      if (info->stride == 0 || b.bytes.size() % info->stride != 0 ||
          b.bytes.size() / info->stride != b.count)
        return Status::failure(fmt("blob %s holds %llu bytes for %llu elements of %u bytes",
                                   info->name.data(), ull(b.bytes.size()), ull(b.count),
                                   info->stride));
      const auto id = static_cast<uint32_t>(b.id);
      if (id >= by_id_.size()) continue;
      if (by_id_[id]) return Status::failure(fmt("blob %s appears twice", info->name.data()));
      by_id_[id] = &b;
    }
    return Status::success();
  }

  uint64_t count(BlobId id) const {
    const BlobBytes* b = by_id_[static_cast<uint32_t>(id)];
    return b ? b->count : 0;
  }
  template <class T>
  Elements<T> get(BlobId id) const {
    const BlobBytes* b = by_id_[static_cast<uint32_t>(id)];
    return b ? Elements<T>{b->bytes.data(), b->count} : Elements<T>{};
  }
  static const char* name(BlobId id) { return find_blob_info(id)->name.data(); }
  // SPEC "Versioning": reserved fields of a newer minor version may carry a
  // meaning this reader does not know; they are ignored then.
  bool newer_minor() const { return opt_.newer_minor; }
  const Grid* grid() const { return opt_.grid; }

  // Blobs that run in parallel: one element each.
  Status same_count(BlobId a, BlobId of) const {
    if (count(a) != count(of))
      return Status::failure(fmt("%s has %llu elements but %s has %llu; they must match", name(a),
                                 ull(count(a)), name(of), ull(count(of))));
    return Status::success();
  }
  // value < count(target)
  Status index(BlobId blob, uint64_t element, const char* field, uint64_t value,
               BlobId target) const {
    if (value >= count(target))
      return Status::failure(fmt("%s[%llu].%s = %llu is out of range (%s has %llu elements)",
                                 name(blob), ull(element), field, ull(value), name(target),
                                 ull(count(target))));
    return Status::success();
  }
  // first + n <= count(target), without overflow (both are < 2^32).
  Status range(BlobId blob, uint64_t element, uint64_t first, uint64_t n, BlobId target) const {
    if (first + n > count(target))
      return Status::failure(
          fmt("%s[%llu] = (first %llu, count %llu) runs past the end of %s (%llu elements)",
              name(blob), ull(element), ull(first), ull(n), name(target), ull(count(target))));
    return Status::success();
  }

 private:
  std::span<const BlobBytes> blobs_;
  ValidateOptions opt_;
  std::array<const BlobBytes*, 64> by_id_{};
};

#define CHECK(expr)     \
  do {                  \
    Status s_ = (expr); \
    if (!s_) return s_; \
  } while (0)

Status check_grid(const Checker& c) {
  const Grid* g = c.grid();
  if (!g) return Status::success();
  // A grid of no cells is a package without static decals (its per-cell
  // blobs must then be empty, check_cells); cells have a positive size.
  if (g->cell_w <= 0 || g->cell_h <= 0)
    return Status::failure(fmt("grid %ux%u with cell %lldx%lld quanta", g->nx, g->ny,
                               (long long)g->cell_w, (long long)g->cell_h));
  // Shaders and the evaluator compute cell coordinates in int32 quanta.
  const int64_t lim = int64_t(1) << 31;
  if (g->origin_x <= -lim || g->origin_x >= lim || g->origin_y <= -lim || g->origin_y >= lim ||
      g->cell_w >= lim || g->cell_h >= lim || g->origin_x + g->cell_w * int64_t(g->nx) >= lim ||
      g->origin_y + g->cell_h * int64_t(g->ny) >= lim)
    return Status::failure("grid exceeds the int32 quantum range");
  return Status::success();
}

Status check_lines(const Checker& c) {
  CHECK(c.same_count(BlobId::line_vertex_line, BlobId::line_vertices));
  CHECK(c.same_count(BlobId::line_corners, BlobId::line_vertices));
  const auto vl = c.get<uint32_t>(BlobId::line_vertex_line);
  for (uint64_t i = 0; i < vl.size(); ++i)
    CHECK(c.index(BlobId::line_vertex_line, i, "line", vl[i], BlobId::line_props));
  const auto props = c.get<LineProps>(BlobId::line_props);
  for (uint64_t i = 0; i < props.size(); ++i) {
    const LineProps p = props[i];
    if (!(p.half_width >= 0.0f && p.half_width < kMaxHalfWidthMetres))
      return Status::failure(fmt("line_props[%llu].half_width = %g is not in [0, 1e7) metres",
                                 ull(i), double(p.half_width)));
    // A clipped outline's ring quad-tree lives in the polygon node arrays
    // (check_polygons() checks every node); its root must be one of them.
    if (p.style & kStyleClipBit)
      CHECK(c.index(BlobId::line_props, i, "clip_node", p.clip_node, BlobId::qt_node));
    else if (p.clip_node != 0 && !c.newer_minor())
      return Status::failure(
          fmt("line_props[%llu].clip_node = %u without style bit 5 (clipped); must be zero", ull(i),
              p.clip_node));
  }
  const auto ranges = c.get<u2>(BlobId::cell_segment_range);
  for (uint64_t i = 0; i < ranges.size(); ++i)
    CHECK(
        c.range(BlobId::cell_segment_range, i, ranges[i][0], ranges[i][1], BlobId::cell_segments));
  const auto segs = c.get<u2>(BlobId::cell_segments);
  for (uint64_t i = 0; i < segs.size(); ++i) {
    CHECK(c.index(BlobId::cell_segments, i, "start", segs[i][0], BlobId::line_vertices));
    CHECK(c.index(BlobId::cell_segments, i, "end", segs[i][1], BlobId::line_vertices));
  }
  return Status::success();
}

Status check_polygons(const Checker& c) {
  CHECK(c.same_count(BlobId::poly_root_node, BlobId::poly_props));
  CHECK(c.same_count(BlobId::qt_node_box, BlobId::qt_node));
  const auto props = c.get<PolyProps>(BlobId::poly_props);
  for (uint64_t i = 0; i < props.size(); ++i) {
    const PolyProps p = props[i];
    if ((p.reserved[0] != 0 || p.reserved[1] != 0) && !c.newer_minor())
      return Status::failure(fmt("poly_props[%llu].reserved is not zero", ull(i)));
    if (p.exterior < -1 || (p.exterior >= 0 && uint64_t(p.exterior) >= props.size()))
      return Status::failure(fmt("poly_props[%llu].exterior = %d is out of range (%llu polygons)",
                                 ull(i), p.exterior, ull(props.size())));
  }
  const auto roots = c.get<uint32_t>(BlobId::poly_root_node);
  for (uint64_t i = 0; i < roots.size(); ++i)
    CHECK(c.index(BlobId::poly_root_node, i, "node", roots[i], BlobId::qt_node));
  // Partial leaves index the v1.3 loop ranges when the package has leaf
  // loops, else the v1.0-1.2 leaf ranges; never both layouts at once.
  const bool loop_layout =
      c.count(BlobId::qt_leaf_loop_range) > 0 || c.count(BlobId::qt_leaf_loops) > 0;
  if (loop_layout && (c.count(BlobId::qt_leaf_range) > 0 || c.count(BlobId::qt_leaf_segments) > 0))
    return Status::failure(
        "qt_leaf_range/qt_leaf_segments (v1.2 layout) and qt_leaf_loop_range/qt_leaf_loops (v1.3) "
        "are both present");
  const BlobId leaf_blob = loop_layout ? BlobId::qt_leaf_loop_range : BlobId::qt_leaf_range;
  const auto nodes = c.get<i2>(BlobId::qt_node);
  for (uint64_t i = 0; i < nodes.size(); ++i) {
    const int32_t type = nodes[i][0], off = nodes[i][1];
    if (type < 0 || type > 3)
      return Status::failure(fmt("qt_node[%llu].type = %d is not a node type 0..3", ull(i), type));
    if (off < 0) return Status::failure(fmt("qt_node[%llu].offset = %d is negative", ull(i), off));
    if (type == int32_t(QtNodeType::internal)) {
      // Children after their parent: every descent ends.
      if (uint64_t(off) <= i)
        return Status::failure(
            fmt("qt_node[%llu].offset = %d: children must come after their parent", ull(i), off));
      CHECK(c.range(BlobId::qt_node, i, uint64_t(off), 4, BlobId::qt_node));
    } else if (type == int32_t(QtNodeType::partial)) {
      CHECK(c.index(BlobId::qt_node, i, "offset", uint64_t(off), leaf_blob));
    }
  }
  // v1.3 leaf loops: loop l holds vertices [end[l-1], end[l]) (end[-1] = 0).
  const auto loop_ranges = c.get<u2>(BlobId::qt_leaf_loop_range);
  for (uint64_t i = 0; i < loop_ranges.size(); ++i)
    CHECK(c.range(BlobId::qt_leaf_loop_range, i, loop_ranges[i][0], loop_ranges[i][1],
                  BlobId::qt_leaf_loops));
  const auto loops = c.get<uint32_t>(BlobId::qt_leaf_loops);
  for (uint64_t i = 0, prev = 0; i < loops.size(); prev = loops[i], ++i) {
    if (loops[i] < prev)
      return Status::failure(
          fmt("qt_leaf_loops[%llu] = %u is less than the previous loop's end %llu", ull(i),
              loops[i], ull(prev)));
    if (loops[i] > c.count(BlobId::qt_leaf_vertices))
      return Status::failure(
          fmt("qt_leaf_loops[%llu] = %u runs past the end of qt_leaf_vertices "
              "(%llu elements)",
              ull(i), loops[i], ull(c.count(BlobId::qt_leaf_vertices))));
  }
  const auto leaves = c.get<u2>(BlobId::qt_leaf_range);
  for (uint64_t i = 0; i < leaves.size(); ++i)
    CHECK(c.range(BlobId::qt_leaf_range, i, leaves[i][0], leaves[i][1], BlobId::qt_leaf_segments));
  const auto lsegs = c.get<u2>(BlobId::qt_leaf_segments);
  for (uint64_t i = 0; i < lsegs.size(); ++i) {
    CHECK(c.index(BlobId::qt_leaf_segments, i, "start", lsegs[i][0], BlobId::qt_leaf_vertices));
    CHECK(c.index(BlobId::qt_leaf_segments, i, "end", lsegs[i][1], BlobId::qt_leaf_vertices));
  }
  // v1.2 leaf segments must be closed runs of consecutive vertices (every
  // writer wrote them so): the GL loader encodes them as v1.3 leaf loops.
  if (leaves.size() > 0) {
    std::vector<layout::u2> r(leaves.size()), sg(lsegs.size());
    for (uint64_t i = 0; i < leaves.size(); ++i) r[i] = leaves[i];
    for (uint64_t i = 0; i < lsegs.size(); ++i) sg[i] = lsegs[i];
    std::vector<layout::u2> loop_range;
    std::vector<uint32_t> loop_end;
    if (!layout::encode_leaves(r, sg, c.count(BlobId::qt_leaf_vertices), loop_range, loop_end))
      return Status::failure(
          "qt_leaf_segments: the segments of a leaf are not closed runs of consecutive vertices "
          "(SPEC.md \"Compact layout (v1.3)\")");
  }
  const auto cranges = c.get<u2>(BlobId::cell_poly_range);
  for (uint64_t i = 0; i < cranges.size(); ++i)
    CHECK(c.range(BlobId::cell_poly_range, i, cranges[i][0], cranges[i][1], BlobId::cell_polys));
  const auto cpolys = c.get<u4>(BlobId::cell_polys);
  for (uint64_t i = 0; i < cpolys.size(); ++i) {
    CHECK(c.index(BlobId::cell_polys, i, "polygon", cpolys[i][0], BlobId::poly_props));
    CHECK(c.index(BlobId::cell_polys, i, "node", cpolys[i][1], BlobId::qt_node));
    CHECK(c.range(BlobId::cell_polys, i, cpolys[i][2], cpolys[i][3], BlobId::cell_holes));
  }
  // v1.3 entries (polygon, node) with hole firsts: one per entry plus one,
  // from 0 to #cell_holes, never decreasing.
  const auto entries = c.get<u2>(BlobId::cell_poly_entries);
  const auto hole_first = c.get<uint32_t>(BlobId::cell_poly_holes);
  if (entries.size() > 0 || hole_first.size() > 0) {
    if (cpolys.size() > 0)
      return Status::failure(
          "cell_polys (v1.2 layout) and cell_poly_entries (v1.3) are both present");
    if (hole_first.size() != entries.size() + 1)
      return Status::failure(
          fmt("cell_poly_holes has %llu elements for %llu cell_poly_entries "
              "(must be entries + 1)",
              ull(hole_first.size()), ull(entries.size())));
    if (hole_first[0] != 0 || hole_first[hole_first.size() - 1] != c.count(BlobId::cell_holes))
      return Status::failure(
          fmt("cell_poly_holes runs from %u to %u; it must run from 0 to %llu "
              "(#cell_holes)",
              hole_first[0], hole_first[hole_first.size() - 1], ull(c.count(BlobId::cell_holes))));
    for (uint64_t i = 0; i < entries.size(); ++i) {
      CHECK(c.index(BlobId::cell_poly_entries, i, "polygon", entries[i][0], BlobId::poly_props));
      CHECK(c.index(BlobId::cell_poly_entries, i, "node", entries[i][1], BlobId::qt_node));
      if (hole_first[i + 1] < hole_first[i])
        return Status::failure(
            fmt("cell_poly_holes[%llu] = %u is less than cell_poly_holes[%llu] = %u", ull(i + 1),
                hole_first[i + 1], ull(i), hole_first[i]));
    }
  }
  const auto holes = c.get<u2>(BlobId::cell_holes);
  for (uint64_t i = 0; i < holes.size(); ++i) {
    CHECK(c.index(BlobId::cell_holes, i, "polygon", holes[i][0], BlobId::poly_props));
    CHECK(c.index(BlobId::cell_holes, i, "node", holes[i][1], BlobId::qt_node));
  }
  return Status::success();
}

// Per-cell list ranges and their BVHs: (first box, leaf slots, internal
// nodes) is a full binary tree inside the box blob whose leaf k is the cell's
// k-th list entry (thesis §4.2.1, Eq. 4.5–4.7). With a grid, one of each per
// cell; a kind that is absent has neither.
Status check_cells(const Checker& c, BlobId range_id, BlobId list_id, BlobId bvh_id, BlobId box_id,
                   BlobId first_id) {
  const auto ranges = c.get<u2>(range_id);
  const auto bvh = c.get<u4>(bvh_id);
  // The kind is absent, or in the v1.3 layout (check_cells_first).
  if (ranges.size() == 0 && bvh.size() == 0 && (c.count(list_id) == 0 || c.count(first_id) > 0))
    return Status::success();
  CHECK(c.same_count(bvh_id, range_id));
  if (const Grid* g = c.grid(); g && ranges.size() != uint64_t(g->nx) * g->ny)
    return Status::failure(fmt("%s has %llu elements for the %llu grid cells",
                               Checker::name(range_id), ull(ranges.size()),
                               ull(uint64_t(g->nx) * g->ny)));
  const uint64_t boxes = c.count(box_id);
  for (uint64_t i = 0; i < bvh.size(); ++i) {
    const u4 b = bvh[i];
    const uint64_t first = b[0], slots = b[1], internal = b[2];
    const bool pow2 = (slots & (slots - 1)) == 0;
    if (slots < ranges[i][1] || !pow2 || (slots > 0 && internal + 1 != slots) ||
        (slots == 0 && internal != 0) || first + slots + internal > boxes)
      return Status::failure(
          fmt("%s[%llu] = (first %llu, leaves %llu, internal %llu) is not a full binary tree over "
              "the cell's %u entries inside %s (%llu boxes)",
              Checker::name(bvh_id), ull(i), ull(first), ull(slots), ull(internal), ranges[i][1],
              Checker::name(box_id), ull(boxes)));
  }
  return Status::success();
}

// v1.3 per-cell firsts: one element per cell plus one, (first entry, first
// node), from (0, 0) to (#list, #boxes); each cell's entries n = x[c+1] -
// x[c] and nodes d = y[c+1] - y[c] form a full binary tree: d = 0 when n =
// 0, else d = 2P - 1 for a power of two P >= n. A kind is in one layout
// only.
Status check_cells_first(const Checker& c, BlobId first_id, BlobId list_id, BlobId box_id,
                         BlobId old_range_id, BlobId old_bvh_id, BlobId old_box_id) {
  const auto first = c.get<u2>(first_id);
  if (first.size() == 0) {
    if (c.count(box_id) > 0)
      return Status::failure(fmt("%s has %llu elements but %s is absent", Checker::name(box_id),
                                 ull(c.count(box_id)), Checker::name(first_id)));
    return Status::success();
  }
  if (c.count(old_range_id) > 0 || c.count(old_bvh_id) > 0 || c.count(old_box_id) > 0)
    return Status::failure(fmt("%s (v1.3) and %s/%s/%s (v1.2 layout) are both present",
                               Checker::name(first_id), Checker::name(old_range_id),
                               Checker::name(old_bvh_id), Checker::name(old_box_id)));
  if (const Grid* g = c.grid(); g && first.size() != uint64_t(g->nx) * g->ny + 1)
    return Status::failure(fmt("%s has %llu elements for the %llu grid cells (must be cells + 1)",
                               Checker::name(first_id), ull(first.size()),
                               ull(uint64_t(g->nx) * g->ny)));
  const u2 f0 = first[0], fn = first[first.size() - 1];
  if (f0[0] != 0 || f0[1] != 0 || fn[0] != c.count(list_id) || fn[1] != c.count(box_id))
    return Status::failure(
        fmt("%s runs from (%u, %u) to (%u, %u); it must run from (0, 0) to "
            "(%llu, %llu), the element counts of %s and %s",
            Checker::name(first_id), f0[0], f0[1], fn[0], fn[1], ull(c.count(list_id)),
            ull(c.count(box_id)), Checker::name(list_id), Checker::name(box_id)));
  for (uint64_t i = 0; i + 1 < first.size(); ++i) {
    const u2 a = first[i], b = first[i + 1];
    if (b[0] < a[0] || b[1] < a[1])
      return Status::failure(fmt("%s[%llu] = (%u, %u) is less than %s[%llu] = (%u, %u)",
                                 Checker::name(first_id), ull(i + 1), b[0], b[1],
                                 Checker::name(first_id), ull(i), a[0], a[1]));
    const uint64_t n = b[0] - a[0], d = b[1] - a[1], p = (d + 1) / 2;
    const bool full = n == 0 ? d == 0 : (d % 2 == 1 && (p & (p - 1)) == 0 && p >= n);
    if (!full)
      return Status::failure(
          fmt("%s[%llu]: %llu nodes are not a full binary tree over the cell's "
              "%llu entries",
              Checker::name(first_id), ull(i), ull(d), ull(n)));
  }
  return Status::success();
}

Status check_dynamic(const Checker& c) {
  CHECK(c.same_count(BlobId::dyn_prev_next, BlobId::dyn_vertices));
  const auto verts = c.get<i4>(BlobId::dyn_vertices);
  for (uint64_t i = 0; i < verts.size(); ++i) {
    if (verts[i][3] < 0)
      return Status::failure(fmt("dyn_vertices[%llu].line = %d is negative", ull(i), verts[i][3]));
    CHECK(c.index(BlobId::dyn_vertices, i, "line", uint64_t(verts[i][3]), BlobId::dyn_line_props));
  }
  const auto links = c.get<i2>(BlobId::dyn_prev_next);
  for (uint64_t i = 0; i < links.size(); ++i)
    for (size_t k = 0; k < 2; ++k) {
      const int32_t v = links[i][k];
      if (v < -1 || (v >= 0 && uint64_t(v) >= verts.size()))
        return Status::failure(fmt("dyn_prev_next[%llu].%s = %d is out of range (%llu vertices)",
                                   ull(i), k == 0 ? "previous" : "next", v, ull(verts.size())));
    }
  const auto starts = c.get<uint32_t>(BlobId::dyn_line_start);
  for (uint64_t i = 0; i < starts.size(); ++i)
    CHECK(c.index(BlobId::dyn_line_start, i, "vertex", starts[i], BlobId::dyn_vertices));
  // The dynamic update walks lines as consecutive vertex runs: line l owns
  // [start[l], start[l+1]), starts increase from 0, and every vertex names
  // the run it lies in.
  if (verts.size() > 0) {
    CHECK(c.same_count(BlobId::dyn_line_start, BlobId::dyn_line_props));
    if (starts.size() == 0 || starts[0] != 0)
      return Status::failure("dyn_line_start[0] must be 0 when dynamic vertices exist");
    for (uint64_t l = 0; l < starts.size(); ++l) {
      const uint64_t end = l + 1 < starts.size() ? starts[l + 1] : verts.size();
      if (end <= starts[l])
        return Status::failure(
            fmt("dyn_line_start[%llu] = %llu does not increase", ull(l + 1), ull(end)));
      for (uint64_t v = starts[l]; v < end; ++v)
        if (uint64_t(verts[v][3]) != l)
          return Status::failure(fmt("dyn_vertices[%llu].line = %d lies in the run of line %llu",
                                     ull(v), verts[v][3], ull(l)));
    }
  }
  const auto props = c.get<LineProps>(BlobId::dyn_line_props);
  for (uint64_t i = 0; i < props.size(); ++i)
    if (props[i].clip_node != 0 && !c.newer_minor())
      return Status::failure(
          fmt("dyn_line_props[%llu].clip_node = %u, must be zero (dynamic lines are never clipped)",
              ull(i), props[i].clip_node));
  return Status::success();
}

Status check_lod(const Checker& c) {
  const auto points = c.get<LodPoint>(BlobId::lod_points);
  for (uint64_t i = 0; i < points.size(); ++i) {
    const LodPoint p = points[i];
    CHECK(c.index(BlobId::lod_points, i, "line", p.line, BlobId::dyn_line_props));
    if ((p.flags & ~kLodPointAlways) != 0)
      return Status::failure(
          fmt("lod_points[%llu].flags = %u, only bit 0 may be set", ull(i), p.flags));
  }
  const auto segs = c.get<LodSegment>(BlobId::lod_segments);
  for (uint64_t i = 0; i < segs.size(); ++i) {
    const LodSegment s = segs[i];
    CHECK(c.index(BlobId::lod_segments, i, "a", s.a, BlobId::lod_points));
    CHECK(c.index(BlobId::lod_segments, i, "b", s.b, BlobId::lod_points));
    if (s.generator != kLodNone)
      CHECK(c.index(BlobId::lod_segments, i, "generator", s.generator, BlobId::lod_points));
    if (s.splitter != kLodNone)
      CHECK(c.index(BlobId::lod_segments, i, "splitter", s.splitter, BlobId::lod_points));
  }
  const auto ranges = c.get<u2>(BlobId::lod_line_range);
  for (uint64_t i = 0; i < ranges.size(); ++i)
    CHECK(c.range(BlobId::lod_line_range, i, ranges[i][0], ranges[i][1], BlobId::lod_segments));
  return Status::success();
}

#undef CHECK

}  // namespace

Status validate_blobs(std::span<const BlobBytes> blobs, const ValidateOptions& options) {
  Checker c(blobs, options);
  if (Status s = c.index_blobs(); !s) return s;
  if (Status s = check_grid(c); !s) return s;
  if (Status s = check_lines(c); !s) return s;
  if (Status s = check_polygons(c); !s) return s;
  if (Status s = check_cells(c, BlobId::cell_segment_range, BlobId::cell_segments,
                             BlobId::line_bvh_range, BlobId::line_bvh_box, BlobId::cell_line_first);
      !s)
    return s;
  if (Status s = check_cells(c, BlobId::cell_poly_range, BlobId::cell_polys, BlobId::poly_bvh_range,
                             BlobId::poly_bvh_box, BlobId::cell_poly_first);
      !s)
    return s;
  if (Status s = check_cells_first(c, BlobId::cell_line_first, BlobId::cell_segments,
                                   BlobId::line_bvh_box16, BlobId::cell_segment_range,
                                   BlobId::line_bvh_range, BlobId::line_bvh_box);
      !s)
    return s;
  if (Status s = check_cells_first(c, BlobId::cell_poly_first, BlobId::cell_poly_entries,
                                   BlobId::poly_bvh_box16, BlobId::cell_poly_range,
                                   BlobId::poly_bvh_range, BlobId::poly_bvh_box);
      !s)
    return s;
  if (Status s = check_dynamic(c); !s) return s;
  return check_lod(c);
}

std::vector<BlobBytes> blobs_of(const Package& package) {
  std::vector<BlobBytes> out;
  for (const BlobView& b : package.blobs())
    if (b.known()) out.push_back({static_cast<BlobId>(b.id), b.count, b.bytes});
  return out;
}

Status validate_indices(const Package& package, const Grid* grid) {
  const std::vector<BlobBytes> blobs = blobs_of(package);
  return validate_blobs(blobs, {grid, package.minor() > kVersionMinor});
}

}  // namespace decal
