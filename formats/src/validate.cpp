// validate.cpp — decal::validate_indices: the structural checks that need
// blob contents (SPEC.md §"Index constraints"). A package that passes can be
// traversed by the shaders (thesis §4.2.1) without any out-of-range read.
#include <array>
#include <cstdio>
#include <string>

#include "decal/inspect.hpp"

namespace decal {
namespace {

using u2 = std::array<uint32_t, 2>;
using u4 = std::array<uint32_t, 4>;
using i2 = std::array<int32_t, 2>;
using i4 = std::array<int32_t, 4>;

std::string fmt(const char* f, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, f, args...);
  return buf;
}

using ull = unsigned long long;

class Checker {
 public:
  explicit Checker(const Package& p) : p_(p) {}

  uint64_t count(BlobId id) const {
    const BlobView* b = p_.find(id);
    return b ? b->count : 0;
  }
  template <class T>
  std::span<const T> get(BlobId id) const {
    return p_.array<T>(id);
  }
  static const char* name(BlobId id) { return find_blob_info(id)->name.data(); }
  // SPEC §Versioning: reserved fields of a newer minor version may carry a
  // meaning this reader does not know; they are ignored then.
  bool newer_minor() const { return p_.minor() > kVersionMinor; }

  // Blobs that hold one element per element of `of` must match its count;
  // an empty dependent blob means the feature is absent.
  Status same_count(BlobId a, BlobId of) const {
    if (count(a) != 0 && count(a) != count(of))
      return Status::failure(fmt("%s has %llu elements but %s has %llu; they must match",
                                 name(a), ull(count(a)), name(of), ull(count(of))));
    return Status::success();
  }
  // index < count(target)
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
      return Status::failure(fmt("%s[%llu] = (first %llu, count %llu) runs past the end of %s "
                                 "(%llu elements)",
                                 name(blob), ull(element), ull(first), ull(n), name(target),
                                 ull(count(target))));
    return Status::success();
  }

 private:
  const Package& p_;
};

#define CHECK(expr)             \
  do {                          \
    Status s_ = (expr);         \
    if (!s_) return s_;         \
  } while (0)

Status check_lines(const Checker& c) {
  CHECK(c.same_count(BlobId::line_vertex_line, BlobId::line_vertices));
  CHECK(c.same_count(BlobId::line_corners, BlobId::line_vertices));
  const auto vl = c.get<uint32_t>(BlobId::line_vertex_line);
  for (size_t i = 0; i < vl.size(); ++i)
    CHECK(c.index(BlobId::line_vertex_line, i, "line", vl[i], BlobId::line_props));
  const auto props = c.get<LineProps>(BlobId::line_props);
  for (size_t i = 0; i < props.size(); ++i) {
    // A clipped outline's ring quad-tree lives in the polygon node arrays
    // (check_polygons() checks every node); its root must be one of them.
    if (props[i].style & kStyleClipBit)
      CHECK(c.index(BlobId::line_props, i, "clip_node", props[i].clip_node, BlobId::qt_node));
    else if (props[i].clip_node != 0 && !c.newer_minor())
      return Status::failure(fmt("line_props[%zu].clip_node = %u without style bit 5 (clipped); "
                                 "must be zero",
                                 i, props[i].clip_node));
  }
  const auto ranges = c.get<u2>(BlobId::cell_segment_range);
  for (size_t i = 0; i < ranges.size(); ++i)
    CHECK(c.range(BlobId::cell_segment_range, i, ranges[i][0], ranges[i][1],
                  BlobId::cell_segments));
  const auto segs = c.get<u2>(BlobId::cell_segments);
  for (size_t i = 0; i < segs.size(); ++i) {
    CHECK(c.index(BlobId::cell_segments, i, "start", segs[i][0], BlobId::line_vertices));
    CHECK(c.index(BlobId::cell_segments, i, "end", segs[i][1], BlobId::line_vertices));
  }
  return Status::success();
}

Status check_polygons(const Checker& c) {
  CHECK(c.same_count(BlobId::poly_root_node, BlobId::poly_props));
  CHECK(c.same_count(BlobId::qt_node_box, BlobId::qt_node));
  const auto props = c.get<PolyProps>(BlobId::poly_props);
  for (size_t i = 0; i < props.size(); ++i) {
    if ((props[i].reserved[0] != 0 || props[i].reserved[1] != 0) && !c.newer_minor())
      return Status::failure(fmt("poly_props[%zu].reserved is not zero", i));
    if (props[i].exterior < -1 || (props[i].exterior >= 0 &&
                                   uint64_t(props[i].exterior) >= props.size()))
      return Status::failure(fmt("poly_props[%zu].exterior = %d is out of range (%zu polygons)",
                                 i, props[i].exterior, props.size()));
  }
  const auto roots = c.get<uint32_t>(BlobId::poly_root_node);
  for (size_t i = 0; i < roots.size(); ++i)
    CHECK(c.index(BlobId::poly_root_node, i, "node", roots[i], BlobId::qt_node));
  const auto nodes = c.get<i2>(BlobId::qt_node);
  for (size_t i = 0; i < nodes.size(); ++i) {
    const int32_t type = nodes[i][0], off = nodes[i][1];
    if (type < 0 || type > 3)
      return Status::failure(fmt("qt_node[%zu].type = %d is not a node type 0..3", i, type));
    if (off < 0)
      return Status::failure(fmt("qt_node[%zu].offset = %d is negative", i, off));
    if (type == int32_t(QtNodeType::internal))
      CHECK(c.range(BlobId::qt_node, i, uint64_t(off), 4, BlobId::qt_node));
    else if (type == int32_t(QtNodeType::partial))
      CHECK(c.index(BlobId::qt_node, i, "offset", uint64_t(off), BlobId::qt_leaf_range));
  }
  const auto leaves = c.get<u2>(BlobId::qt_leaf_range);
  for (size_t i = 0; i < leaves.size(); ++i)
    CHECK(c.range(BlobId::qt_leaf_range, i, leaves[i][0], leaves[i][1],
                  BlobId::qt_leaf_segments));
  const auto lsegs = c.get<u2>(BlobId::qt_leaf_segments);
  for (size_t i = 0; i < lsegs.size(); ++i) {
    CHECK(c.index(BlobId::qt_leaf_segments, i, "start", lsegs[i][0], BlobId::qt_leaf_vertices));
    CHECK(c.index(BlobId::qt_leaf_segments, i, "end", lsegs[i][1], BlobId::qt_leaf_vertices));
  }
  const auto cranges = c.get<u2>(BlobId::cell_poly_range);
  for (size_t i = 0; i < cranges.size(); ++i)
    CHECK(c.range(BlobId::cell_poly_range, i, cranges[i][0], cranges[i][1], BlobId::cell_polys));
  const auto cpolys = c.get<u4>(BlobId::cell_polys);
  for (size_t i = 0; i < cpolys.size(); ++i) {
    CHECK(c.index(BlobId::cell_polys, i, "polygon", cpolys[i][0], BlobId::poly_props));
    CHECK(c.index(BlobId::cell_polys, i, "node", cpolys[i][1], BlobId::qt_node));
    CHECK(c.range(BlobId::cell_polys, i, cpolys[i][2], cpolys[i][3], BlobId::cell_holes));
  }
  const auto holes = c.get<u2>(BlobId::cell_holes);
  for (size_t i = 0; i < holes.size(); ++i) {
    CHECK(c.index(BlobId::cell_holes, i, "polygon", holes[i][0], BlobId::poly_props));
    CHECK(c.index(BlobId::cell_holes, i, "node", holes[i][1], BlobId::qt_node));
  }
  return Status::success();
}

Status check_bvh(const Checker& c, BlobId range_id, BlobId box_id) {
  const auto ranges = c.get<u4>(range_id);
  for (size_t i = 0; i < ranges.size(); ++i)
    CHECK(c.range(range_id, i, ranges[i][0], uint64_t(ranges[i][1]) + ranges[i][2], box_id));
  return Status::success();
}

Status check_dynamic(const Checker& c) {
  CHECK(c.same_count(BlobId::dyn_prev_next, BlobId::dyn_vertices));
  const auto verts = c.get<i4>(BlobId::dyn_vertices);
  if (c.count(BlobId::dyn_line_props) != 0)
    for (size_t i = 0; i < verts.size(); ++i) {
      if (verts[i][3] < 0)
        return Status::failure(fmt("dyn_vertices[%zu].line = %d is negative", i, verts[i][3]));
      CHECK(c.index(BlobId::dyn_vertices, i, "line", uint64_t(verts[i][3]),
                    BlobId::dyn_line_props));
    }
  const auto links = c.get<i2>(BlobId::dyn_prev_next);
  for (size_t i = 0; i < links.size(); ++i)
    for (int k = 0; k < 2; ++k) {
      const int32_t v = links[i][k];
      if (v < -1 || (v >= 0 && uint64_t(v) >= verts.size()))
        return Status::failure(fmt("dyn_prev_next[%zu].%s = %d is out of range (%zu vertices)", i,
                                   k == 0 ? "previous" : "next", v, verts.size()));
    }
  const auto starts = c.get<uint32_t>(BlobId::dyn_line_start);
  for (size_t i = 0; i < starts.size(); ++i)
    CHECK(c.index(BlobId::dyn_line_start, i, "vertex", starts[i], BlobId::dyn_vertices));
  const auto props = c.get<LineProps>(BlobId::dyn_line_props);
  for (size_t i = 0; i < props.size(); ++i)
    if (props[i].clip_node != 0 && !c.newer_minor())
      return Status::failure(fmt("dyn_line_props[%zu].clip_node = %u, must be zero (dynamic lines "
                                 "are never clipped)",
                                 i, props[i].clip_node));
  return Status::success();
}

Status check_lod(const Checker& c) {
  const auto points = c.get<LodPoint>(BlobId::lod_points);
  for (size_t i = 0; i < points.size(); ++i) {
    CHECK(c.index(BlobId::lod_points, i, "line", points[i].line, BlobId::dyn_line_props));
    if ((points[i].flags & ~kLodPointAlways) != 0)
      return Status::failure(fmt("lod_points[%zu].flags = %u, only bit 0 may be set", i,
                                 points[i].flags));
  }
  const auto segs = c.get<LodSegment>(BlobId::lod_segments);
  for (size_t i = 0; i < segs.size(); ++i) {
    CHECK(c.index(BlobId::lod_segments, i, "a", segs[i].a, BlobId::lod_points));
    CHECK(c.index(BlobId::lod_segments, i, "b", segs[i].b, BlobId::lod_points));
    if (segs[i].generator != kLodNone)
      CHECK(c.index(BlobId::lod_segments, i, "generator", segs[i].generator, BlobId::lod_points));
    if (segs[i].splitter != kLodNone)
      CHECK(c.index(BlobId::lod_segments, i, "splitter", segs[i].splitter, BlobId::lod_points));
  }
  const auto ranges = c.get<u2>(BlobId::lod_line_range);
  for (size_t i = 0; i < ranges.size(); ++i)
    CHECK(c.range(BlobId::lod_line_range, i, ranges[i][0], ranges[i][1], BlobId::lod_segments));
  return Status::success();
}

#undef CHECK

}  // namespace

Status validate_indices(const Package& package) {
  const Checker c(package);
  if (Status s = check_lines(c); !s) return s;
  if (Status s = check_polygons(c); !s) return s;
  if (Status s = check_bvh(c, BlobId::line_bvh_range, BlobId::line_bvh_box); !s) return s;
  if (Status s = check_bvh(c, BlobId::poly_bvh_range, BlobId::poly_bvh_box); !s) return s;
  if (Status s = check_dynamic(c); !s) return s;
  return check_lod(c);
}

}  // namespace decal
