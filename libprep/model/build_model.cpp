// libprep/model/build_model.cpp — stage 4 driver: SceneFeatures -> DecalModel
// (thesis §4.2.1). Order of work: lines and their widened segments, polygon
// quad-trees, the decal grid over everything, assignment of segments and
// quad-tree parts to cells, per-cell BVHs sorted by drawing order, then the
// dynamic lines and LOD segments (prep_model_terrain, when linked).
//
// Determinism: every parallel loop writes to its own slot; results are
// concatenated in input order and sorted with total keys, so the arrays are
// byte-identical at any thread count.
#include <tbb/enumerable_thread_specific.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <sstream>

#include <decal/layout.hpp>

#include "detail.hpp"
#include "prep/error.hpp"
#include "prep/model.hpp"
#include "prep/progress.hpp"
#include "prep/stage_error.hpp"

namespace prep {

namespace detail {

std::vector<uint32_t> draw_ranks(const std::vector<DrawKey>& keys) {
  std::vector<uint32_t> idx(keys.size());
  std::iota(idx.begin(), idx.end(), 0u);
  std::sort(idx.begin(), idx.end(), [&](uint32_t a, uint32_t b) {
    const DrawKey& x = keys[a];
    const DrawKey& y = keys[b];
    if (x.layer != y.layer) return x.layer > y.layer;  // later layer on top
    if (x.kind != y.kind) return x.kind < y.kind;      // a layer's lines over its polygons
    if (x.primary != y.primary) return x.primary > y.primary;
    if (x.fid != y.fid) return x.fid < y.fid;
    if (x.part != y.part) return x.part < y.part;
    return x.input < y.input;
  });
  std::vector<uint32_t> rank(keys.size());
  for (uint32_t r = 0; r < idx.size(); ++r) rank[idx[r]] = r;
  return rank;
}

}  // namespace detail

using namespace detail;

namespace {

struct PolyRing {
  std::vector<QPoint> ring;
  int32_t exterior = -1;  // package index of the exterior (interiors only)
  uint32_t scene_index = 0;
};

QBox box_of(const ivec4& b) {
  return {b[0], b[1], b[2], b[3]};
}
QBox intersect(const QBox& a, const QBox& b) {
  return {std::max(a.x0, b.x0), std::max(a.y0, b.y0), std::min(a.x1, b.x1), std::min(a.y1, b.y1)};
}
// Box `a` with each coordinate clamped into `b`'s ranges: intersect() where
// they meet; otherwise the side or corner of `b` nearest `a`, which is no
// farther from a point of `b` on either axis than `a` is (a min_width_px
// leaf box in a cell its stored width does not reach; readers grow it by
// the reach, formats/SPEC.md "Minimum widths").
QBox clamp_into(const QBox& a, const QBox& b) {
  auto c = [](int64_t v, int64_t lo, int64_t hi) { return std::clamp(v, lo, hi); };
  return {c(a.x0, b.x0, b.x1), c(a.y0, b.y0, b.y1), c(a.x1, b.x0, b.x1), c(a.y1, b.y0, b.y1)};
}
ivec4 to_ivec4(const QBox& b) {
  return {int32_t(b.x0), int32_t(b.y0), int32_t(b.x1), int32_t(b.y1)};
}
bool contains(const ivec4& outer, const QBox& in) {
  return outer[0] <= in.x0 && outer[1] <= in.y0 && in.x1 <= outer[2] && in.y1 <= outer[3];
}

// Quantised ring without repeated consecutive or closing vertices (`where`:
// see quantise).
std::vector<QPoint> quantise_ring(const Ring& r, double& err, const WhereFn& where) {
  std::vector<QPoint> q;
  q.reserve(r.size());
  for (const Point2& p : r) {
    QPoint v = quantise(p, err, where);
    if (q.empty() || !(q.back() == v)) q.push_back(v);
  }
  while (q.size() > 1 && q.back() == q.front()) q.pop_back();
  return q;
}

// One (cell, polygon) pair: culling node and BVH leaf box (cell-relative
// u16, decal::layout::Box16Encoder).
struct CellPoly {
  uint32_t cell;
  uint32_t poly;
  uint32_t cull;
  uvec2 box;
};

// Grows `v` to `n` elements; when that needs a new buffer, reserves `scale`
// times `n`, so that arrays filled block by block reach their final size
// with few copies and little slack.
template <class T>
void grow_to(std::vector<T>& v, size_t n, double scale) {
  if (n > v.capacity()) v.reserve(std::max(n, size_t(double(n) * scale)));
  v.resize(n);
}

// Appends quad-trees `trees` (local indices), in order, to the model's node
// arrays and returns the index of each root node. The arrays grow once per
// call, to sizes from prefix sums (`scale`: see grow_to), and the trees are
// copied and rebased in parallel (each to its own range), so the bytes do not
// depend on the thread count; the trees are freed as they are copied.
std::vector<uint32_t> append_quadtrees(std::vector<PolyQuadTree>& trees, DecalModel& m,
                                       double scale = 1.0) {
  struct Base {
    size_t node, range, loop, vert;
  };
  std::vector<Base> base(trees.size() + 1);
  base[0] = {m.qt_node.size(), m.qt_leaf_loop_range.size(), m.qt_leaf_loops.size(),
             m.qt_leaf_vertices.size()};
  for (size_t i = 0; i < trees.size(); ++i) {
    const PolyQuadTree& t = trees[i];
    base[i + 1] = {base[i].node + t.node.size(), base[i].range + t.leaf_range.size(),
                   base[i].loop + t.leaf_loops.size(), base[i].vert + t.leaf_vertices.size()};
    m.stats.qt_depth_capped += t.depth_capped;
    m.stats.qt_max_leaf_segments = std::max(m.stats.qt_max_leaf_segments, t.max_leaf_segments);
    m.stats.qt_partial_leaves += t.leaf_range.size();
  }
  const Base& end = base.back();
  grow_to(m.qt_node, end.node, scale);
  grow_to(m.qt_node_box, end.node, scale);
  grow_to(m.qt_leaf_loop_range, end.range, scale);
  grow_to(m.qt_leaf_loops, end.loop, scale);
  grow_to(m.qt_leaf_vertices, end.vert, scale);
  tbb::parallel_for(size_t(0), trees.size(), [&](size_t i) {
    PolyQuadTree& t = trees[i];
    const Base& b = base[i];
    for (size_t k = 0; k < t.node.size(); ++k) {
      ivec2 n = t.node[k];
      if (n[0] == int32_t(decal::QtNodeType::internal)) n[1] += int32_t(b.node);
      if (n[0] == int32_t(decal::QtNodeType::partial)) n[1] += int32_t(b.range);
      m.qt_node[b.node + k] = n;
    }
    std::copy(t.box.begin(), t.box.end(), m.qt_node_box.begin() + ptrdiff_t(b.node));
    for (size_t k = 0; k < t.leaf_range.size(); ++k)
      m.qt_leaf_loop_range[b.range + k] = {t.leaf_range[k][0] + uint32_t(b.loop),
                                           t.leaf_range[k][1]};
    for (size_t k = 0; k < t.leaf_loops.size(); ++k)
      m.qt_leaf_loops[b.loop + k] = t.leaf_loops[k] + uint32_t(b.vert);
    std::copy(t.leaf_vertices.begin(), t.leaf_vertices.end(),
              m.qt_leaf_vertices.begin() + ptrdiff_t(b.vert));
    t = PolyQuadTree();  // free early
  });
  std::vector<uint32_t> roots(trees.size());
  for (size_t i = 0; i < trees.size(); ++i) roots[i] = uint32_t(base[i].node);
  return roots;
}

// Exact outlines (thesis §3.6 made exact). An inset/offset outline keeps one
// half of its doubled-width band; the thesis keeps the half on one side of
// each directed segment, which leaks past other edges of the ring where the
// polygon is narrower than the width or an edge is shorter than its
// neighbour's miter reach (thesis Fig. 4.8). Instead every closed inset or
// offset ring gets a quad-tree of its own quantised ring (the polygon
// builder, same node arrays, referenced by no polygon and no cell), and the
// evaluator keeps a point of the band iff that ring's even-odd query says it
// lies on the kept side: band ∩ ring or band − ring, per ring, exactly what
// the GEOS oracle of the accuracy tests computes.
void add_outline_clip_trees(const ModelOptions& options, DecalModel& m) {
  struct Clip {
    uint32_t line, first, count;
  };
  std::vector<Clip> clips;
  const size_t nv = m.line_vertices.size();
  for (size_t v = 0; v < nv;) {
    const uint32_t line = m.line_vertex_line[v];
    size_t e = v;
    while (e < nv && m.line_vertex_line[e] == line) ++e;
    const uint32_t style = m.line_props[line].style;
    const auto mode =
        decal::OutlineMode((style & decal::kStyleOutlineMask) >> decal::kStyleOutlineShift);
    // build_lines() leaves rings of fewer than 3 distinct vertices open.
    if (mode != decal::OutlineMode::normal && (style & decal::kStyleClosedBit) && e - v >= 3)
      clips.push_back({line, uint32_t(v), uint32_t(e - v)});
    v = e;
  }
  std::vector<PolyQuadTree> trees(clips.size());
  std::vector<int> orientation(clips.size(), 0);  // sign of the ring's area
  tbb::parallel_for(size_t(0), clips.size(), [&](size_t i) {
    const Clip& c = clips[i];
    std::vector<QPoint> ring(c.count);
    __extension__ __int128 area2 = 0;  // exact shoelace on quanta
    for (uint32_t k = 0; k < c.count; ++k) {
      const ivec2& a = m.line_vertices[c.first + k];
      const ivec2& b = m.line_vertices[c.first + (k + 1) % c.count];
      ring[k] = {a[0], a[1]};
      area2 += __int128(int64_t(a[0]) * b[1]) - __int128(int64_t(b[0]) * a[1]);
    }
    orientation[i] = area2 > 0 ? 1 : area2 < 0 ? -1 : 0;
    if (orientation[i] != 0)
      trees[i] = build_quadtree(ring, options.qt_leaf_capacity, options.qt_max_depth);
  });
  const std::vector<uint32_t> roots = append_quadtrees(trees, m);
  for (size_t i = 0; i < clips.size(); ++i) {
    if (orientation[i] == 0) continue;  // zero area: nothing is inside; one-sided test
    decal::LineProps& pr = m.line_props[clips[i].line];
    const bool inset = ((pr.style & decal::kStyleOutlineMask) >> decal::kStyleOutlineShift) ==
                       uint32_t(decal::OutlineMode::inset);
    // Inset keeps the left side: the inside of a CCW ring, the outside of a CW one.
    const bool keep_inside = inset == (orientation[i] > 0);
    pr.clip_node = roots[i];
    pr.style |= decal::kStyleClipBit | (keep_inside ? decal::kStyleClipInsideBit : 0u);
  }
}

// The polygons of the scene as quantised rings: exteriors in input order,
// each followed by its interiors.
struct PolygonRings {
  std::vector<PolyRing> rings;
  std::vector<uint32_t> ext_index;                  // package index of each exterior
  std::vector<uint32_t> order;                      // drawing rank of each ring
  std::vector<std::vector<uint32_t>> solid_leaves;  // non-outside leaves per ring
  bool is_hole(size_t r) const { return rings[r].exterior >= 0; }
};

void check_options(const ModelOptions& options) {
  if (options.qt_leaf_capacity == 0 || options.qt_max_depth > 24)
    fail<usage_error>(kBuildStage,
                      "quad-tree leaf capacity must be >= 1 and max depth <= 24 (got " +
                          std::to_string(options.qt_leaf_capacity) + ", " +
                          std::to_string(options.qt_max_depth) + ")");
}

// Quantises every polygon ring (in parallel), drops rings of fewer than 3
// distinct quanta (noted in the manifest) and appends a drawing key per kept
// exterior to `draw_keys`.
PolygonRings quantise_polygons(const SceneFeatures& scene, DecalModel& m,
                               std::vector<DrawKey>& draw_keys) {
  const size_t np = scene.polygons.size();
  std::vector<std::vector<std::vector<QPoint>>> qrings(np);  // [polygon][ring]
  std::vector<double> qerr(np, 0.0);
  tbb::parallel_for(size_t(0), np, [&](size_t i) {
    const ScenePolygon& p = scene.polygons[i];
    const WhereFn where = [&] {
      std::ostringstream w;
      w << "layer '" << (p.layer < scene.layers.size() ? scene.layers[p.layer].name : "?")
        << "' fid " << p.fid << " part " << p.part;
      return w.str();
    };
    qrings[i].push_back(quantise_ring(p.shell, qerr[i], where));
    for (const Ring& h : p.holes)
      qrings[i].push_back(quantise_ring(h, qerr[i], [&] { return where() + " hole"; }));
  });
  PolygonRings out;
  for (size_t i = 0; i < np; ++i) {
    const ScenePolygon& p = scene.polygons[i];
    m.max_representation_error = std::max(m.max_representation_error, qerr[i]);
    if (p.layer >= scene.layers.size())
      fail<input_error>(kBuildStage, "polygon fid " + std::to_string(p.fid) +
                                         " refers to layer index " + std::to_string(p.layer) +
                                         ", but the scene has " +
                                         std::to_string(scene.layers.size()) + " layers");
    auto drop = [&](const std::string& why) {
      ManifestEntry e;
      e.layer = scene.layers[p.layer].name;
      e.fid = p.fid;
      e.part = p.part;
      e.action = ManifestAction::dropped;
      e.reason = stage_message(kBuildStage, why);
      m.manifest.entries.push_back(e);
    };
    if (qrings[i][0].size() < 3) {
      drop("exterior ring has fewer than 3 distinct vertices at 1 mm resolution");
      continue;
    }
    const int32_t ext = int32_t(out.rings.size());
    out.rings.push_back({std::move(qrings[i][0]), -1, uint32_t(i)});
    out.ext_index.push_back(uint32_t(ext));
    draw_keys.push_back({std::isnan(p.order_value) ? p.area : p.order_value, p.layer,
                         DrawKind::polygon, p.fid, p.part, uint32_t(i)});
    for (size_t h = 1; h < qrings[i].size(); ++h) {
      if (qrings[i][h].size() < 3) {
        drop("interior ring " + std::to_string(h - 1) +
             " has fewer than 3 distinct vertices at 1 mm resolution; polygon kept without it");
        continue;
      }
      out.rings.push_back({std::move(qrings[i][h]), ext, uint32_t(i)});
    }
  }
  return out;
}

// One rank space for lines and exterior polygons (`draw_keys`: the lines
// first, then the exteriors); interiors take their exterior's rank.
void assign_ranks(const std::vector<DrawKey>& draw_keys, size_t n_lines, PolygonRings& pr,
                  DecalModel& m) {
  const std::vector<uint32_t> rank = draw_ranks(draw_keys);
  for (size_t i = 0; i < n_lines; ++i) m.line_props[i].order = rank[i];
  pr.order.assign(pr.rings.size(), 0);
  for (size_t k = 0; k < pr.ext_index.size(); ++k) pr.order[pr.ext_index[k]] = rank[n_lines + k];
  for (size_t r = 0; r < pr.rings.size(); ++r)
    if (pr.is_hole(r)) pr.order[r] = pr.order[size_t(pr.rings[r].exterior)];
}

// One quad-tree per ring (in parallel), concatenated into the model's node
// arrays with the polygon properties, then the outline clip trees. Rings go
// in blocks of about a sixteenth of the vertices: a block's trees are built
// (each thread reusing its working arrays, each tree copied out at its exact
// size), appended and freed before the next block, and each ring is freed
// once its tree is built, so the trees never exist twice in full.
void build_polygon_trees(const SceneFeatures& scene, const ModelOptions& options, PolygonRings& pr,
                         DecalModel& m) {
  std::vector<PolyRing>& rings = pr.rings;
  ProgressStage quadtree_stage(options.progress, "build.quadtrees", rings.size(), "rings");
  size_t total_vertices = 0;
  for (const PolyRing& r : rings) total_vertices += r.ring.size();
  const size_t block_vertices = std::max<size_t>(size_t(1) << 16, total_vertices / 16);
  struct Local {
    QuadTreeScratch scratch;
    PolyQuadTree tree;
  };
  tbb::enumerable_thread_specific<Local> local;
  std::vector<PolyQuadTree> trees;
  m.poly_root_node.reserve(rings.size());
  size_t done_vertices = 0;
  for (size_t b0 = 0; b0 < rings.size();) {
    size_t b1 = b0, v = 0;
    while (b1 < rings.size() && (b1 == b0 || v < block_vertices)) v += rings[b1++].ring.size();
    trees.clear();
    trees.resize(b1 - b0);
    tbb::parallel_for(b0, b1, [&](size_t r) {
      Local& l = local.local();
      build_quadtree(rings[r].ring, options.qt_leaf_capacity, options.qt_max_depth, l.tree,
                     l.scratch);
      trees[r - b0] = l.tree;  // a copy holds no spare capacity
      std::vector<QPoint>().swap(rings[r].ring);
      quadtree_stage.add();
    });
    done_vertices += v;
    // The arrays' final sizes, projected from the share of vertices done
    // (at least a quarter more, so that a misjudged projection costs a few
    // copies, not one per block).
    const double scale =
        std::max(1.25, 1.05 * double(total_vertices) / double(std::max<size_t>(done_vertices, 1)));
    const std::vector<uint32_t> roots = append_quadtrees(trees, m, scale);
    m.poly_root_node.insert(m.poly_root_node.end(), roots.begin(), roots.end());
    b0 = b1;
  }
  trees = {};
  m.poly_props.resize(rings.size());
  for (size_t r = 0; r < rings.size(); ++r) {
    const ScenePolygon& sp = scene.polygons[rings[r].scene_index];
    decal::PolyProps& pp = m.poly_props[r];
    pp.rgba = rings[r].exterior < 0
                  ? resolve_color(scene.layers[sp.layer].style.color, sp.color_value)
                  : 0u;
    pp.order = pr.order[r];
    pp.exterior = rings[r].exterior;
    pp.value = float(sp.color_value);
    pp.layer = sp.layer;
    pp.feature = stored_feature_id(sp.fid);
    pp.reserved[0] = pp.reserved[1] = 0;
  }
  m.stats.quadtrees = rings.size();
  add_outline_clip_trees(options, m);
  quadtree_stage.finish();
  m.stats.qt_nodes = m.qt_node.size();
  if (m.stats.qt_depth_capped > 0) {
    std::ostringstream note;
    note << m.stats.qt_depth_capped << " quad-tree leaves reached the maximum depth "
         << options.qt_max_depth << " with more than " << options.qt_leaf_capacity
         << " segments (fullest leaf: " << m.stats.qt_max_leaf_segments << ")";
    m.manifest.notes.push_back(stage_message(kBuildStage, note.str()));
  }
}

// Non-outside leaves of every ring's tree: the polygon parts that go to cells.
std::vector<std::vector<uint32_t>> solid_leaves(const DecalModel& m, size_t n_rings) {
  std::vector<std::vector<uint32_t>> out(n_rings);
  tbb::parallel_for(size_t(0), n_rings, [&](size_t r) {
    std::vector<uint32_t> stack{m.poly_root_node[r]};
    while (!stack.empty()) {
      uint32_t n = stack.back();
      stack.pop_back();
      const auto type = decal::QtNodeType(m.qt_node[n][0]);
      if (type == decal::QtNodeType::internal) {
        for (int c = 3; c >= 0; --c) stack.push_back(uint32_t(m.qt_node[n][1] + c));
      } else if (type != decal::QtNodeType::outside) {
        out[r].push_back(n);
      }
    }
  });
  return out;
}

template <class T>
uint64_t bytes_of(const std::vector<T>& v) {
  return uint64_t(v.size()) * sizeof(T);
}

// The static blobs made before the grid: lines and quad-trees.
uint64_t static_geometry_bytes(const DecalModel& m) {
  return bytes_of(m.line_vertices) + bytes_of(m.line_vertex_line) + bytes_of(m.line_props) +
         bytes_of(m.line_corners) + bytes_of(m.poly_props) + bytes_of(m.poly_root_node) +
         bytes_of(m.qt_node_box) + bytes_of(m.qt_node) + bytes_of(m.qt_leaf_loop_range) +
         bytes_of(m.qt_leaf_loops) + bytes_of(m.qt_leaf_vertices);
}

// The decal grid over every segment and solid polygon leaf, weighed against
// the grid-independent blobs (the per-cell lists and BVHs are counted in
// choose_grid).
GridParams choose_model_grid(const std::vector<SegmentShape>& shapes, const PolygonRings& pr,
                             const ModelOptions& options, const DecalModel& m, double* cell_bytes) {
  QBox extent;
  auto grow = [&](const QBox& b) {
    if (extent.empty())
      extent = b;
    else
      extent = {std::min(extent.x0, b.x0), std::min(extent.y0, b.y0), std::max(extent.x1, b.x1),
                std::max(extent.y1, b.y1)};
  };
  for (const SegmentShape& s : shapes) grow(s.box);
  for (size_t r = 0; r < pr.rings.size(); ++r) grow(box_of(m.qt_node_box[m.poly_root_node[r]]));
  // The grid covers the strokes too; shaders and the evaluator address its
  // cells in int32 quanta (formats/SPEC.md "Validation"), so it must end
  // inside that range.
  if (!extent.empty() && (std::max({-extent.x0, -extent.y0, extent.x1, extent.y1}) > kMaxQuanta)) {
    std::ostringstream msg;
    msg.precision(4);
    msg << "the decal grid over the data and its line strokes would reach "
        << double(std::max({-extent.x0, -extent.y0, extent.x1, extent.y1})) *
               decal::kQuantumMetres / 1000.0
        << " km from the package origin; int32 millimetre positions hold 2147 km (narrower "
           "--width or scene widths, or a tileset)";
    fail<resource_error>(kBuildStage, msg.str());
  }
  GridInput gin;
  gin.extent = extent;
  gin.shapes = &shapes;
  gin.ring_leaves = &pr.solid_leaves;
  gin.node_box = &m.qt_node_box;
  std::vector<uint8_t> ring_is_hole(pr.rings.size());
  for (size_t r = 0; r < pr.rings.size(); ++r) ring_is_hole[r] = pr.is_hole(r);
  gin.ring_is_hole = &ring_is_hole;
  // The v1.2 layout the grid's byte model counts: one leaf segment (8 bytes)
  // per leaf vertex instead of the loops' ends.
  gin.geometry_bytes = static_geometry_bytes(m) - bytes_of(m.qt_leaf_loops) +
                       m.qt_leaf_vertices.size() * sizeof(uvec2);
  return choose_grid(gin, options, cell_bytes);
}

// One (cell, line segment) pair: the segment's box clipped to the cell.
struct SegEntry {
  uint32_t cell, order, start, end;
  ivec4 box;
};

// Segments -> cells by their exact shapes (thesis §4.2.1), sorted by cell,
// drawing rank and segment. Row by row in parallel: the shapes are listed
// once per cell row their boxes reach (in shape order), each row makes and
// sorts its own entries, and the rows are concatenated in row order, so the
// result is the one sort of all entries whatever the thread count, at
// O(entries log(entries per row)).
std::vector<SegEntry> line_cell_entries(const DecalModel& m,
                                        const std::vector<SegmentShape>& shapes,
                                        ProgressStage& cells_stage) {
  const GridParams& g = m.grid;
  const size_t ny = g.ny;
  std::vector<std::array<uint32_t, 2>> rows(shapes.size(), {1, 0});  // first, last row
  tbb::parallel_for(tbb::blocked_range<size_t>(0, shapes.size(), 4096),
                    [&](const tbb::blocked_range<size_t>& r) {
                      for (size_t i = r.begin(); i != r.end(); ++i) {
                        int64_t x0, y0, x1, y1;
                        if (cell_range(g, shapes[i].box, x0, y0, x1, y1))
                          rows[i] = {uint32_t(y0), uint32_t(y1)};
                      }
                    });
  std::vector<uint64_t> first(ny + 1, 0);
  for (const auto& r : rows)
    for (uint32_t iy = r[0]; iy <= r[1]; ++iy) ++first[iy + 1];
  for (size_t iy = 0; iy < ny; ++iy) first[iy + 1] += first[iy];
  std::vector<uint32_t> listed(first[ny]);
  {
    std::vector<uint64_t> fill(first.begin(), first.end() - 1);
    for (size_t i = 0; i < shapes.size(); ++i)
      for (uint32_t iy = rows[i][0]; iy <= rows[i][1]; ++iy) listed[fill[iy]++] = uint32_t(i);
  }
  std::vector<std::vector<SegEntry>> per_row(ny);
  tbb::parallel_for(size_t(0), ny, [&](size_t iy) {
    std::vector<SegEntry>& out = per_row[iy];
    for (uint64_t j = first[iy]; j < first[iy + 1]; ++j) {
      const SegmentShape& s = shapes[listed[j]];
      const uint32_t order = m.line_props[s.line].order;
      for_each_cell_in_rows(g, s, int64_t(iy), int64_t(iy), [&](uint32_t cell) {
        const int64_t ix = cell % g.nx;
        QBox cb = cell_box(g, ix, int64_t(iy));
        cb = {cb.x0 - 1, cb.y0 - 1, cb.x1 + 1, cb.y1 + 1};
        out.push_back({cell, order, s.start, s.end, to_ivec4(clamp_into(s.leaf_box, cb))});
      });
    }
    std::sort(out.begin(), out.end(), [](const SegEntry& a, const SegEntry& b) {
      if (a.cell != b.cell) return a.cell < b.cell;
      if (a.order != b.order) return a.order < b.order;
      return a.start < b.start;
    });
  });
  std::vector<size_t> at(ny + 1, 0);
  for (size_t iy = 0; iy < ny; ++iy) at[iy + 1] = at[iy] + per_row[iy].size();
  std::vector<SegEntry> entries(at[ny]);
  tbb::parallel_for(size_t(0), ny, [&](size_t iy) {
    std::copy(per_row[iy].begin(), per_row[iy].end(), entries.begin() + ptrdiff_t(at[iy]));
    std::vector<SegEntry>().swap(per_row[iy]);
  });
  cells_stage.add(m.line_props.size());
  return entries;
}

// Reused buffers of ring_cell_entries (one per thread).
struct RingCellScratch {
  std::vector<std::array<int64_t, 4>> range;    // per leaf: its cells x0, y0, x1, y1
  std::vector<QBox> dense;                      // union per cell of the ring's cell rectangle
  std::vector<std::pair<uint32_t, QBox>> hits;  // (cell, part) where the rectangle is sparse
  std::vector<CellPoly> out;
};

// The (cell, ring) pairs of one ring, in cell order: its solid leaves
// clipped to each cell they touch, merged per cell, with the culling node:
// the deepest node whose box holds every part of the polygon that can
// matter in that cell. The parts of a cell are merged by a box union, which
// does not depend on their order: in a dense array over the cell rectangle
// the leaves reach (row-major, so in cell order) when that rectangle holds
// at most 4 times the cells the leaves touch, else sorted by cell.
std::vector<CellPoly> ring_cell_entries(const DecalModel& m, const GridMap& map,
                                        const decal::layout::Box16Encoder& box16, uint32_t r,
                                        const std::vector<uint32_t>& leaves,
                                        RingCellScratch& scratch) {
  const GridParams& g = m.grid;
  std::vector<std::array<int64_t, 4>>& range = scratch.range;
  range.clear();
  int64_t rx0 = std::numeric_limits<int64_t>::max(), ry0 = rx0, rx1 = -1, ry1 = -1;
  uint64_t touched = 0;
  for (uint32_t n : leaves) {
    std::array<int64_t, 4> c;
    const ivec4& nb = m.qt_node_box[n];
    if (!map.range({nb[0], nb[1], nb[2], nb[3]}, c[0], c[1], c[2], c[3])) c = {1, 1, 0, 0};
    range.push_back(c);
    if (c[0] > c[2]) continue;
    rx0 = std::min(rx0, c[0]);
    ry0 = std::min(ry0, c[1]);
    rx1 = std::max(rx1, c[2]);
    ry1 = std::max(ry1, c[3]);
    touched += uint64_t(c[2] - c[0] + 1) * uint64_t(c[3] - c[1] + 1);
  }
  if (touched == 0) return {};
  std::vector<CellPoly>& out = scratch.out;
  out.clear();
  auto emit = [&](uint32_t cell, const QBox& u) {
    uint32_t node = m.poly_root_node[r];
    for (;;) {
      if (m.qt_node[node][0] != int32_t(decal::QtNodeType::internal)) break;
      uint32_t next = node;
      for (int c = 0; c < 4; ++c) {
        const uint32_t ch = uint32_t(m.qt_node[node][1] + c);
        if (contains(m.qt_node_box[ch], u)) {
          next = ch;
          break;
        }
      }
      if (next == node) break;
      node = next;
    }
    out.push_back({cell, r, node, box16(cell, to_ivec4(u))});
  };
  auto unite = [](QBox& u, const QBox& b) {
    if (u.empty()) {
      u = b;
      return;
    }
    u = {std::min(u.x0, b.x0), std::min(u.y0, b.y0), std::max(u.x1, b.x1), std::max(u.y1, b.y1)};
  };
  // Leaf `lb`'s part in cell (ix, iy): clipped to the cell expanded by one quantum.
  auto part_of = [&](const QBox& lb, int64_t ix, int64_t iy) {
    QBox cb = cell_box(g, ix, iy);
    return intersect(lb, {cb.x0 - 1, cb.y0 - 1, cb.x1 + 1, cb.y1 + 1});
  };
  // Every non-empty (cell, leaf part), leaf by leaf.
  auto for_each_part = [&](auto&& fn) {
    for (size_t k = 0; k < leaves.size(); ++k) {
      const auto& c = range[k];
      const QBox lb = box_of(m.qt_node_box[leaves[k]]);
      for (int64_t iy = c[1]; iy <= c[3]; ++iy)
        for (int64_t ix = c[0]; ix <= c[2]; ++ix) {
          const QBox part = part_of(lb, ix, iy);
          if (!part.empty()) fn(ix, iy, part);
        }
    }
  };
  const uint64_t w = uint64_t(rx1 - rx0 + 1), area = w * uint64_t(ry1 - ry0 + 1);
  if (area <= std::max<uint64_t>(4 * touched, 16)) {
    std::vector<QBox>& dense = scratch.dense;
    dense.assign(area, QBox{});
    for_each_part([&](int64_t ix, int64_t iy, const QBox& part) {
      unite(dense[uint64_t(iy - ry0) * w + uint64_t(ix - rx0)], part);
    });
    for (int64_t iy = ry0; iy <= ry1; ++iy)
      for (int64_t ix = rx0; ix <= rx1; ++ix) {
        const QBox& u = dense[uint64_t(iy - ry0) * w + uint64_t(ix - rx0)];
        if (!u.empty()) emit(uint32_t(ix + int64_t(g.nx) * iy), u);
      }
  } else {
    std::vector<std::pair<uint32_t, QBox>>& hits = scratch.hits;
    hits.clear();
    for_each_part([&](int64_t ix, int64_t iy, const QBox& part) {
      hits.push_back({uint32_t(ix + int64_t(g.nx) * iy), part});
    });
    std::sort(hits.begin(), hits.end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
    for (size_t i = 0; i < hits.size();) {
      QBox u;
      size_t j = i;
      for (; j < hits.size() && hits[j].first == hits[i].first; ++j) unite(u, hits[j].second);
      emit(hits[i].first, u);
      i = j;
    }
  }
  return std::vector<CellPoly>(out.begin(), out.end());
}

// Polygons -> cells with culling nodes (thesis §4.2.1): exteriors and holes
// apart, each sorted by cell, drawing rank, exterior and ring. The rings'
// entries (in parallel, each ring's in cell order) are bucketed by cell in
// ring order, then each cell's few entries are sorted by the rest of the
// key, in parallel: a total order (a ring has one entry per cell), so the
// result does not depend on the thread count.
void polygon_cell_entries(const DecalModel& m, const PolygonRings& pr, ProgressStage& cells_stage,
                          std::vector<CellPoly>& ext_entries, std::vector<CellPoly>& hole_entries) {
  const size_t nr = pr.rings.size();
  std::vector<std::vector<CellPoly>> per_ring(nr);
  tbb::enumerable_thread_specific<RingCellScratch> scratch;
  const GridMap map(m.grid);
  const decal::layout::Box16Encoder box16(cell_grid(m.grid));
  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, nr, 16), [&](const tbb::blocked_range<size_t>& range) {
        RingCellScratch& s = scratch.local();
        for (size_t r = range.begin(); r != range.end(); ++r) {
          per_ring[r] = ring_cell_entries(m, map, box16, uint32_t(r), pr.solid_leaves[r], s);
          cells_stage.add();
        }
      });
  scratch.clear();
  const size_t ncells = size_t(m.grid.nx) * m.grid.ny;
  auto ext_of = [&](uint32_t poly) {
    return pr.rings[poly].exterior < 0 ? poly : uint32_t(pr.rings[poly].exterior);
  };
  auto poly_less = [&](const CellPoly& a, const CellPoly& b) {
    if (pr.order[a.poly] != pr.order[b.poly]) return pr.order[a.poly] < pr.order[b.poly];
    if (ext_of(a.poly) != ext_of(b.poly)) return ext_of(a.poly) < ext_of(b.poly);
    return a.poly < b.poly;
  };
  for (const bool holes : {false, true}) {
    std::vector<CellPoly>& dst = holes ? hole_entries : ext_entries;
    // Counting sort by cell: first[c + 1] counts cell c, then holds where
    // it starts; placing advances first[c] to cell c's end, and the shift
    // back restores the starts.
    std::vector<uint32_t> first(ncells + 1, 0);
    uint64_t total = 0;
    for (size_t r = 0; r < nr; ++r)
      if (pr.is_hole(r) == holes) {
        total += per_ring[r].size();
        for (const CellPoly& e : per_ring[r]) ++first[e.cell + 1];
      }
    if (total > 0xffffffffULL)
      fail<resource_error>(kBuildStage, "2^32 or more (cell, polygon) entries");
    for (size_t c = 0; c < ncells; ++c) first[c + 1] += first[c];
    dst.resize(total);
    for (size_t r = 0; r < nr; ++r) {
      if (pr.is_hole(r) != holes) continue;
      for (const CellPoly& e : per_ring[r]) dst[first[e.cell]++] = e;
      std::vector<CellPoly>().swap(per_ring[r]);
    }
    for (size_t c = ncells; c > 0; --c) first[c] = first[c - 1];
    first[0] = 0;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, ncells, 4096),
                      [&](const tbb::blocked_range<size_t>& range) {
                        for (size_t c = range.begin(); c != range.end(); ++c)
                          if (first[c + 1] - first[c] > 1)
                            std::sort(dst.begin() + ptrdiff_t(first[c]),
                                      dst.begin() + ptrdiff_t(first[c + 1]), poly_less);
                      });
  }
}

// The per-cell lists (segments, exteriors with their holes) and the per-cell
// BVHs over them, in the v1.3 layout (formats/SPEC.md "Compact layout
// (v1.3)"). Each kind's entries are freed as soon as its arrays are made;
// a kind without entries has no per-cell arrays.
void fill_cells(std::vector<SegEntry>&& seg_entries, std::vector<CellPoly>&& ext_entries,
                std::vector<CellPoly>&& hole_entries, const PolygonRings& pr, DecalModel& m) {
  const size_t ncells = size_t(m.grid.nx) * m.grid.ny;
  const decal::layout::Box16Encoder box16(cell_grid(m.grid));
  std::vector<uint32_t> first;
  auto count_cells = [&](const auto& entries) {
    if (entries.size() > 0xffffffffULL)
      fail<resource_error>(kBuildStage, "2^32 or more (cell, primitive) entries");
    first.assign(ncells + 1, 0);
    for (const auto& e : entries) ++first[e.cell + 1];
    for (size_t c = 0; c < ncells; ++c) first[c + 1] += first[c];
  };
  if (!seg_entries.empty()) {
    count_cells(seg_entries);
    m.cell_segments.resize(seg_entries.size());
    for (size_t i = 0; i < seg_entries.size(); ++i)
      m.cell_segments[i] = {seg_entries[i].start, seg_entries[i].end};
    build_bvhs(
        first,
        [&](uint64_t cell, uint32_t f, uint32_t n, uvec2* out) {
          for (uint32_t k = 0; k < n; ++k) out[k] = box16(cell, seg_entries[f + k].box);
        },
        m.cell_line_first, m.line_bvh_box16);
  }
  std::vector<SegEntry>().swap(seg_entries);
  if (!ext_entries.empty()) {
    m.cell_poly_entries.reserve(ext_entries.size());
    m.cell_poly_holes.reserve(ext_entries.size() + 1);
    m.cell_holes.reserve(hole_entries.size());
    size_t h = 0;
    for (const CellPoly& e : ext_entries) {
      m.cell_poly_holes.push_back(uint32_t(m.cell_holes.size()));
      // Holes of this exterior in this cell are contiguous in hole_entries
      // (same sort key prefix); skip holes whose exterior is absent here.
      while (h < hole_entries.size() &&
             (hole_entries[h].cell < e.cell || (hole_entries[h].cell == e.cell &&
                                                pr.order[hole_entries[h].poly] < pr.order[e.poly])))
        ++h;
      while (h < hole_entries.size() && hole_entries[h].cell == e.cell &&
             uint32_t(pr.rings[hole_entries[h].poly].exterior) == e.poly) {
        m.cell_holes.push_back({hole_entries[h].poly, hole_entries[h].cull});
        ++h;
      }
      m.cell_poly_entries.push_back({e.poly, e.cull});
    }
    m.cell_poly_holes.push_back(uint32_t(m.cell_holes.size()));
    std::vector<CellPoly>().swap(hole_entries);
    count_cells(ext_entries);
    build_bvhs(
        first,
        [&](uint64_t, uint32_t f, uint32_t n, uvec2* out) {
          for (uint32_t k = 0; k < n; ++k) out[k] = ext_entries[f + k].box;
        },
        m.cell_poly_first, m.poly_bvh_box16);
  }
  std::vector<CellPoly>().swap(ext_entries);
  std::vector<CellPoly>().swap(hole_entries);
  m.stats.poly_cell_entries = m.cell_poly_entries.size();
  m.stats.hole_cell_entries = m.cell_holes.size();
}

}  // namespace

double min_width_pixel_limit(double resolution, double side, double whole) {
  return std::max({2.0 * resolution, side / 512.0, whole / 256.0});
}

DecalModel build_model(const SceneFeatures& scene, const ModelOptions& options,
                       const std::string& dem) {
  std::optional<tbb::global_control> threads;
  if (options.threads > 0)
    threads.emplace(tbb::global_control::max_allowed_parallelism, options.threads);
  check_options(options);

  DecalModel m;
  m.frame = scene.frame;
  m.extent = scene.extent;
  m.manifest = scene.manifest;

  // Lines: vertices, properties, corners, widened segments.
  std::vector<SegmentShape> shapes;
  std::vector<DrawKey> draw_keys;  // lines first, then exterior polygons
  build_lines(scene, options, m, shapes, draw_keys);
  const size_t n_lines = draw_keys.size();
  m.stats.line_segments = shapes.size();

  // Polygons: quantised rings, drawing ranks, one quad-tree per ring.
  PolygonRings rings = quantise_polygons(scene, m, draw_keys);
  assign_ranks(draw_keys, n_lines, rings, m);
  build_polygon_trees(scene, options, rings, m);
  rings.solid_leaves = solid_leaves(m, rings.rings.size());

  // The decal grid, then segments and polygon parts to cells, and the BVHs.
  double cell_bytes = 0;
  m.grid = choose_model_grid(shapes, rings, options, m, options.on_grid ? &cell_bytes : nullptr);
  if (uint64_t(m.grid.nx) * m.grid.ny > 0xffffffffULL)
    fail<resource_error>(kBuildStage, "decal grid has too many cells");
  if (options.on_grid) {
    options.on_grid(
        {uint64_t(m.grid.nx) * m.grid.ny, cell_bytes, double(static_geometry_bytes(m))});
  }
  ProgressStage cells_stage(options.progress, "build.cells",
                            m.line_props.size() + rings.rings.size(), "items");
  std::vector<SegEntry> seg_entries = line_cell_entries(m, shapes, cells_stage);
  m.stats.line_cell_entries = seg_entries.size();
  std::vector<CellPoly> ext_entries, hole_entries;
  polygon_cell_entries(m, rings, cells_stage, ext_entries, hole_entries);
  fill_cells(std::move(seg_entries), std::move(ext_entries), std::move(hole_entries), rings, m);
  cells_stage.finish();

  // Dynamic lines and LOD.
  ProgressStage dynamic_stage(options.progress, "build.dynamic", scene.dynamic_lines.size(),
                              "lines");
  build_dynamic(scene, options, dem, m);
  dynamic_stage.finish();
  return m;
}

}  // namespace prep
