// libprep/model/quadtree.cpp — polygon quad-trees (thesis §4.2.1 "Polygon
// Quad-Trees"): rectangular nodes, leaf capacity and maximum depth, child
// boxes expanded by one quantum, node types 0..3, leaf polygons closed with
// closing segments, and exact (integer) classification.
//
// Exactness. Every node carries the parity (inside/outside) of the ring at its
// centre under the evaluator's even-odd rule, evaluated EXACTLY with an
// orientation predicate in 128-bit integers on integer coordinates (doubled,
// so that box centres are integers). The root's parity is a full crossing count; a child's is its
// parent's, flipped by every ring edge the path parent-centre -> child-centre
// crosses (only edges of the parent's list can). The evaluator's rule
// "edge straddles q.y (half-open: y > q.y) and meets the ray at x > q.x" is
// the true parity at the symbolically perturbed point q + (e1, e2), e2 << e1,
// so it is a function of position and path differences are exact.
//
// Leaf polygons. A partial leaf stores the runs ("chains") of consecutive
// ring edges that meet its closed box, unclipped (original vertices, so no
// rounded intersection point ever moves the boundary). Each chain is closed
// by closing segments that never enter the box: from each chain end straight
// away from the box to a frame one quantum outside the root box, then along
// the frame. Inside the box the leaf polygon and the ring then differ by a
// cycle that lies outside the box, so their parities differ by a constant;
// if the constant is 1 (checked exactly at the leaf centre) the frame itself
// is added once more. Result: for every point of the closed leaf box the
// even-odd test on the leaf polygon equals the even-odd test on the ring.
#include <algorithm>
#include <array>
#include <span>

#include "detail.hpp"

namespace prep::detail {
namespace {

__extension__ typedef __int128 int128;  // products of 33-bit differences

// Doubled integer coordinates (|v| < 2^33), so box centres are integers.
using P2 = QtPoint2;
inline P2 dbl(const QPoint& p) {
  return {2 * p.x, 2 * p.y};
}

// Sign of the orientation of (p, q, r): > 0 when r lies left of p->q. Exact:
// differences are below 2^34, products below 2^68, well inside int128.
inline int orientation(const P2& p, const P2& q, const P2& r) {
  const int128 d =
      int128(q.x() - p.x()) * (r.y() - p.y()) - int128(q.y() - p.y()) * (r.x() - p.x());
  return (d > 0) - (d < 0);
}

// Evaluator rule at q (doubled coordinates): does edge a-b cross the ray
// from q towards +x?
inline bool ray_crosses(const P2& a, const P2& b, const P2& q) {
  bool ya = a.y() > q.y(), yb = b.y() > q.y();
  if (ya == yb) return false;
  const P2& lo = ya ? b : a;
  const P2& hi = ya ? a : b;
  return orientation(lo, hi, q) > 0;
}

// For an edge straddling the vertical line x + e1: is its crossing above the
// perturbed point (x + e1, y + e2)?
inline bool crossing_above(const P2& a, const P2& b, int64_t x, int64_t y) {
  const P2& l = a.x() < b.x() ? a : b;
  const P2& r = a.x() < b.x() ? b : a;
  const int o = orientation(l, r, P2{x, y});
  if (o < 0) return true;  // point below the edge's line
  if (o > 0) return false;
  return r.y() > l.y();  // on the line: the slope decides (e2 << e1)
}

// Parity change along the vertical path (x, y1) -> (x, y2), perturbed.
inline bool vertical_flip(const P2& a, const P2& b, int64_t x, int64_t y1, int64_t y2) {
  if ((a.x() > x) == (b.x() > x)) return false;
  return crossing_above(a, b, x, y1) != crossing_above(a, b, x, y2);
}

// Closed segment vs closed box, exact (int128 orientation).
inline bool segment_meets_box(const QPoint& a, const QPoint& b, const QBox& bx) {
  if (std::max(a.x, b.x) < bx.x0 || std::min(a.x, b.x) > bx.x1 || std::max(a.y, b.y) < bx.y0 ||
      std::min(a.y, b.y) > bx.y1)
    return false;
  const int128 dx = b.x - a.x, dy = b.y - a.y;
  int pos = 0, neg = 0;
  const int64_t cx[4] = {bx.x0, bx.x1, bx.x1, bx.x0}, cy[4] = {bx.y0, bx.y0, bx.y1, bx.y1};
  for (int i = 0; i < 4; ++i) {
    int128 s = dx * (cy[i] - a.y) - dy * (cx[i] - a.x);
    if (s > 0)
      ++pos;
    else if (s < 0)
      ++neg;
    else
      return true;
  }
  return pos > 0 && neg > 0;
}

using Work = QtWork;

ivec4 to_ivec4(const QBox& b) {
  return {int32_t(b.x0), int32_t(b.y0), int32_t(b.x1), int32_t(b.y1)};
}

class LeafPolygonBuilder {
 public:
  LeafPolygonBuilder(const std::vector<QPoint>& ring, const QBox& root)
      : ring_(ring), fx0_(root.x0 - 1), fy0_(root.y0 - 1), fx1_(root.x1 + 1), fy1_(root.y1 + 1) {}

  // Appends the leaf polygon of `w` (a partial leaf; `edges` its sorted ring
  // edges) to `t`.
  void build(const Work& w, std::span<const uint32_t> edges, PolyQuadTree& t) {
    const size_t n = ring_.size();
    const uint32_t first_loop = uint32_t(t.leaf_loops.size());
    auto member = [&](uint32_t e) { return std::binary_search(edges.begin(), edges.end(), e); };
    if (edges.size() == n) {
      loop_begin(t);
      for (size_t i = 0; i < n; ++i) loop_add(t, ring_[i]);
      loop_end(t);
    } else {
      for (uint32_t e : edges) {
        if (member(uint32_t((e + n - 1) % n))) continue;  // not the start of a chain
        loop_begin(t);
        uint32_t k = e;
        loop_add(t, ring_[k]);
        while (member(k)) {
          k = uint32_t((k + 1) % n);
          loop_add(t, ring_[k]);
        }
        // Close: chain end -> frame -> along the frame -> chain start.
        const QPoint end = ring_[k], start = ring_[e];
        QPoint xe = exit_point(end, w.box), xs = exit_point(start, w.box);
        loop_add(t, xe);
        walk_frame(t, xe, xs);
        loop_add(t, xs);
        loop_end(t);
      }
    }
    // Parity fix at the leaf centre (exact).
    const P2 c{w.box.x0 + w.box.x1, w.box.y0 + w.box.y1};
    bool leaf_parity = false;
    for (size_t l = first_loop; l < t.leaf_loops.size(); ++l) {
      const uint32_t begin = l > 0 ? t.leaf_loops[l - 1] : 0, end = t.leaf_loops[l];
      for (uint32_t v = begin; v < end; ++v) {
        const ivec2& a = t.leaf_vertices[v];
        const ivec2& b = t.leaf_vertices[v + 1 < end ? v + 1 : begin];
        leaf_parity ^= ray_crosses(dbl({a[0], a[1]}), dbl({b[0], b[1]}), c);
      }
    }
    if (leaf_parity != w.parity) {
      loop_begin(t);
      loop_add(t, {fx0_, fy0_});
      loop_add(t, {fx1_, fy0_});
      loop_add(t, {fx1_, fy1_});
      loop_add(t, {fx0_, fy1_});
      loop_end(t);
    }
    t.leaf_range.push_back({first_loop, uint32_t(t.leaf_loops.size()) - first_loop});
  }

 private:
  // A chain end lies outside the closed box; move straight away from the box
  // to the frame, so the closing segment never enters the box.
  QPoint exit_point(const QPoint& p, const QBox& b) const {
    if (p.x < b.x0) return {fx0_, p.y};
    if (p.x > b.x1) return {fx1_, p.y};
    if (p.y < b.y0) return {p.x, fy0_};
    return {p.x, fy1_};
  }
  // Position along the frame, counter-clockwise from its lower-left corner.
  int64_t frame_pos(const QPoint& p) const {
    const int64_t w = fx1_ - fx0_, h = fy1_ - fy0_;
    if (p.y == fy0_) return p.x - fx0_;
    if (p.x == fx1_) return w + (p.y - fy0_);
    if (p.y == fy1_) return w + h + (fx1_ - p.x);
    return 2 * w + h + (fy1_ - p.y);
  }
  void walk_frame(PolyQuadTree& t, const QPoint& from, const QPoint& to) {
    const int64_t w = fx1_ - fx0_, h = fy1_ - fy0_, per = 2 * (w + h);
    const int64_t a = frame_pos(from);
    int64_t b = frame_pos(to);
    if (b < a) b += per;
    const int64_t cpos[4] = {w, w + h, 2 * w + h, per};
    const QPoint corner[4] = {{fx1_, fy0_}, {fx1_, fy1_}, {fx0_, fy1_}, {fx0_, fy0_}};
    for (int lap = 0; lap < 2; ++lap)
      for (int i = 0; i < 4; ++i) {
        int64_t p = cpos[i] + lap * per;
        if (p > a && p < b) loop_add(t, corner[i]);
      }
  }
  void loop_begin(PolyQuadTree& t) { loop_first_ = uint32_t(t.leaf_vertices.size()); }
  void loop_add(PolyQuadTree& t, const QPoint& p) {
    const ivec2 v{int32_t(p.x), int32_t(p.y)};
    if (t.leaf_vertices.size() > loop_first_ && t.leaf_vertices.back() == v) return;
    t.leaf_vertices.push_back(v);
  }
  void loop_end(PolyQuadTree& t) {
    uint32_t last = uint32_t(t.leaf_vertices.size());
    if (last > loop_first_ + 1 && t.leaf_vertices.back() == t.leaf_vertices[loop_first_]) {
      t.leaf_vertices.pop_back();
      --last;
    }
    if (last - loop_first_ < 2) {  // degenerate; cannot happen for a real chain
      t.leaf_vertices.resize(loop_first_);
      return;
    }
    t.leaf_loops.push_back(last);
  }

  const std::vector<QPoint>& ring_;
  int64_t fx0_, fy0_, fx1_, fy1_;
  uint32_t loop_first_ = 0;
};

}  // namespace

void build_quadtree(const std::vector<QPoint>& ring, uint32_t leaf_capacity, uint32_t max_depth,
                    PolyQuadTree& t, QuadTreeScratch& scratch) {
  t.box.clear();
  t.node.clear();
  t.leaf_range.clear();
  t.leaf_loops.clear();
  t.leaf_vertices.clear();
  t.depth_capped = 0;
  t.max_leaf_segments = 0;
  const size_t n = ring.size();
  QBox root{ring[0].x, ring[0].y, ring[0].x, ring[0].y};
  for (const QPoint& p : ring) {
    root.x0 = std::min(root.x0, p.x);
    root.y0 = std::min(root.y0, p.y);
    root.x1 = std::max(root.x1, p.x);
    root.y1 = std::max(root.y1, p.y);
  }
  std::vector<P2>& v2 = scratch.doubled;
  v2.resize(n + 1);
  for (size_t i = 0; i < n; ++i) v2[i] = dbl(ring[i]);
  v2[n] = v2[0];  // edge i is v2[i] -> v2[i + 1]

  // Breadth first, one level at a time: the nodes of a level and their edge
  // lists in two flat arrays, the next level's in two more. Children are
  // numbered in the order their parents are visited, as a FIFO queue would.
  std::vector<Work>& level = scratch.level;
  std::vector<Work>& next = scratch.next_level;
  std::vector<uint32_t>& edges = scratch.edges;
  std::vector<uint32_t>& next_edges = scratch.next_edges;
  level.clear();
  edges.resize(n);
  for (size_t i = 0; i < n; ++i) edges[i] = uint32_t(i);
  Work rw;
  rw.box = root;
  rw.count = uint32_t(n);
  {
    // Exact crossing count at the root centre (integer orientation).
    const P2 c{root.x0 + root.x1, root.y0 + root.y1};
    for (size_t i = 0; i < n; ++i) rw.parity ^= ray_crosses(v2[i], v2[i + 1], c);
  }
  level.push_back(rw);

  LeafPolygonBuilder leaves(ring, root);
  t.box.push_back(to_ivec4(root));
  t.node.push_back({0, 0});
  constexpr int64_t kEps = 1;  // child boxes overlap their siblings by this many quanta
  for (uint32_t depth = 0; !level.empty(); ++depth) {
    next.clear();
    next_edges.clear();
    for (const Work& w : level) {
      const std::span<const uint32_t> we(edges.data() + w.first, w.count);
      const int64_t bw = w.box.x1 - w.box.x0, bh = w.box.y1 - w.box.y0;
      const bool tiny = bw <= 4 && bh <= 4;
      const bool leaf = w.count <= leaf_capacity || depth >= max_depth || tiny;
      if (leaf) {
        t.max_leaf_segments = std::max(t.max_leaf_segments, w.count);
        if (w.count == 0) {
          t.node[w.id] = {
              int32_t(w.parity ? decal::QtNodeType::inside : decal::QtNodeType::outside), 0};
        } else {
          if (w.count > leaf_capacity) ++t.depth_capped;
          t.node[w.id] = {int32_t(decal::QtNodeType::partial), int32_t(t.leaf_range.size())};
          leaves.build(w, we, t);
        }
        continue;
      }
      const int64_t mx = (w.box.x0 + w.box.x1) >> 1, my = (w.box.y0 + w.box.y1) >> 1;
      const uint32_t first_child = uint32_t(t.box.size());
      t.node[w.id] = {int32_t(decal::QtNodeType::internal), int32_t(first_child)};
      const int64_t pcx = w.box.x0 + w.box.x1, pcy = w.box.y0 + w.box.y1;
      // Children SW, SE, NW, NE; rows (south, north) share the vertical leg
      // of the path from the parent's centre and the ray's start on it.
      Work cw[4];
      int64_t ccx[4], ccy[4];
      for (int c = 0; c < 4; ++c) {
        const bool east = c & 1, north = c & 2;
        QBox& b = cw[c].box;
        b.x0 = east ? std::max(mx - kEps, w.box.x0) : w.box.x0;
        b.x1 = east ? w.box.x1 : std::min(mx + kEps, w.box.x1);
        b.y0 = north ? std::max(my - kEps, w.box.y0) : w.box.y0;
        b.y1 = north ? w.box.y1 : std::min(my + kEps, w.box.y1);
        ccx[c] = b.x0 + b.x1;
        ccy[c] = b.y0 + b.y1;
        cw[c].parity = w.parity;
        cw[c].id = first_child + uint32_t(c);
      }
      // One pass over the parent's edges sorts them into the children's
      // lists (each in ring order, so sorted) and flips each child's parity
      // by the edges that cross the path from the parent's centre to the
      // child's. That path lies in the child's closed box (the parent's
      // centre is within a quantum of the split lines), so only an edge
      // that meets the box can cross it.
      std::array<std::vector<uint32_t>, 4>& child = scratch.child_edges;
      bool parity[4];
      P2 q1[4], q2[4];
      for (int c = 0; c < 4; ++c) {
        child[size_t(c)].clear();
        parity[c] = w.parity;
        q1[c] = {pcx, ccy[c]};
        q2[c] = {ccx[c], ccy[c]};
      }
      for (uint32_t e : we) {
        const QPoint& a = ring[e];
        const QPoint& b = ring[e + 1 < n ? e + 1 : 0];
        const int64_t ex0 = std::min(a.x, b.x), ex1 = std::max(a.x, b.x);
        const int64_t ey0 = std::min(a.y, b.y), ey1 = std::max(a.y, b.y);
        for (int c = 0; c < 4; ++c) {
          const QBox& bx = cw[c].box;
          if (ex1 < bx.x0 || ex0 > bx.x1 || ey1 < bx.y0 || ey0 > bx.y1) continue;
          const bool inside = ex0 >= bx.x0 && ex1 <= bx.x1 && ey0 >= bx.y0 && ey1 <= bx.y1;
          if (!inside && !segment_meets_box(a, b, bx)) continue;
          child[size_t(c)].push_back(e);
          const P2& da = v2[e];
          const P2& db = v2[e + 1];
          parity[c] ^= vertical_flip(da, db, pcx, pcy, ccy[c]);
          parity[c] ^= ray_crosses(da, db, q1[c]) != ray_crosses(da, db, q2[c]);
        }
      }
      for (int c = 0; c < 4; ++c) {
        cw[c].first = uint32_t(next_edges.size());
        next_edges.insert(next_edges.end(), child[size_t(c)].begin(), child[size_t(c)].end());
        cw[c].count = uint32_t(child[size_t(c)].size());
        cw[c].parity = parity[c];
        t.box.push_back(to_ivec4(cw[c].box));
        t.node.push_back({0, 0});
        next.push_back(cw[c]);
      }
    }
    std::swap(level, next);
    std::swap(edges, next_edges);
  }
}

PolyQuadTree build_quadtree(const std::vector<QPoint>& ring, uint32_t leaf_capacity,
                            uint32_t max_depth) {
  PolyQuadTree t;
  QuadTreeScratch scratch;
  build_quadtree(ring, leaf_capacity, max_depth, t, scratch);
  return t;
}

}  // namespace prep::detail
