// libprep/evaluate/evaluate.cpp — the CPU evaluator of static decals.
//
// ============================================================================
// THE STATIC DECAL QUERY (thesis Algorithm 3.5, §4.4.1). The GLSL shader
// mirrors this block step by step; change both together.
// ============================================================================
// Notation: q = decal::kQuantumMetres (1 mm). Stored positions are int32
// quanta relative to the package origin. The query point P is given in metres
// relative to the origin; Pq = P / q is its position in quanta (real valued).
// GLSL: keep Pq as an integer part plus a fraction and form every difference
// "stored int - Pq" as float(int - int_part) - fraction, so no absolute
// coordinate is ever a float.
//
// 1. Cell (Eq. 4.3/4.4): ix = floor((Pq.x - grid.origin_x) / cell_w),
//    iy likewise; outside [0,nx) x [0,ny) -> nothing covers P (transparent).
//    cell = ix + nx * iy.
// 2. Box test used everywhere: P in box (xmin,ymin,xmax,ymax) <=>
//    xmin <= Pq.x <= xmax and ymin <= Pq.y <= ymax (closed). Empty boxes have
//    xmin > xmax and contain nothing.
// 3. BVH traversal (stack-less, Eq. 4.5-4.7), one for lines, one for polygons:
//      (first, P, I, _) = *_bvh_range[cell]; if P == 0 skip. i = 0.
//      loop: if P in box[first + i]:
//              if i < I: i = 2i + 1; continue            // descend left
//              k = i - I; handle leaf k (list entry k of the cell)
//            while i > 0 and i is even: i = (i - 1) / 2   // climb from right children
//            if i == 0: stop;  i = i + 1                   // right sibling
//    Leaves are in drawing order, so leaf k is visited before leaf k+1.
//    Leaves k >= the cell's list count (padding slots) are skipped.
// 4. Merge and composite. Lines and exterior polygons share one rank space
//    (LineProps.order, PolyProps.order; 0 = top; formats/SPEC.md "Drawing
//    order"). The two traversals are two streams in rank order; take the
//    next leaf of the stream whose rank is smaller (a line on a tie) and
//    handle it (steps 5, 7). Packages older than format 1.2 ranked lines and
//    polygons separately and drew every line over every polygon: there a
//    polygon's rank is read as order + the number of lines
//    (StaticView::polygon_rank_bias). Compositing is front to back, colours
//    straight alpha, R in the low byte:
//      C += (1 - A) * a * rgb;  A += (1 - A) * a;  stop everything once
//      A >= 0.999.
// 5. Line leaf k: (s, e) = cell_segments[cell_segment_range[cell].x + k];
//    line = line_vertex_line[s]; props = line_props[line]. If `line` is the
//    last line decided, skip (a line contributes once; its segments are
//    consecutive in leaf order). Else test the segment (step 6): "covered"
//    composites props.rgba and remembers `line`; "clipped" only remembers
//    `line` (the ring test of step 6 says no segment of it covers P);
//    "none" goes on.
// 6. Segment test, in metres relative to a = line_vertices[s]:
//      e = (b - a) * q, d = (Pq - a) * q, hw = props.half_width,
//      Ca = line_corners[s], Cb = line_corners[e] (the vertex e).
//      cross(u, v) = u.x v.y - u.y v.x.   null(v) <=> v == (0, 0).
//      Triangle test T(A, B, C, d): the three values cross(B-A, d-A),
//      cross(C-B, d-B), cross(A-C, d-C) are all >= 0 or all <= 0.
//    round: t = clamp(dot(d,e)/dot(e,e), 0, 1); covered <=> |d - t e|^2 <= hw^2.
//    miter: ma = Ca.miter, or if null: Ca.bevel_out negated when
//             cross(e, Ca.bevel_out) < 0 (the left normal);
//           mb = Cb.miter, or if null: Cb.bevel_in made left the same way;
//           covered <=> T(-ma, e - mb, e + mb, d) or T(-ma, e + mb, ma, d)
//                   or (null(Ca.miter) and |d|^2 <= hw^2)
//                   or (null(Cb.miter) and |d - e|^2 <= hw^2).
//    bevel: n = Ca.bevel_out; c = cross(e, n); s = cross(e, d) / c;
//           t = cross(d, n) / c; covered <=> (0 <= t <= 1 and |s| <= 1)
//             or (null(Ca.bevel_in) ? |d|^2 <= hw^2 : T(0, Ca.bevel_in, Ca.bevel_out, d))
//             or (null(Cb.bevel_out) ? |d - e|^2 <= hw^2
//                                    : T(e, e + Cb.bevel_in, e + Cb.bevel_out, d)).
//    Not covered: "none". Normal outline mode: "covered".
//    Clipped outlines (style bit 5, kStyleClipBit; closed inset/offset rings,
//    miter): the two-sided band above, cut by the line's own ring: "covered"
//    if Q(props.clip_node) (step 8) equals style bit 6 (kStyleClipInsideBit),
//    else "clipped". This is band ∩ ring (or band − ring) exactly, where the
//    thesis's one-sided test below leaks past other edges of a narrow ring
//    (Fig. 4.8).
//    Other inset/offset lines (open; only ever stored with miter): K = +1 for
//    inset, -1 for offset, and a covered point is kept ("covered", else
//    "none") only if K * cross(e, d) >= 0 and
//      at b, if !null(Cb.bevel_out): o = sign(cross(e, Cb.bevel_in)) (+1 when
//        the outer side is the left); if K * o < 0 (the turn is towards the
//        kept side) also require K * dot(d - e, o * Cb.bevel_out) >= 0;
//      at a, if !null(Ca.bevel_in): o = sign(cross(e, Ca.bevel_out)); if
//        K * o < 0 also require K * dot(d, o * Ca.bevel_in) >= 0.
//    (The kept side of a corner turning towards it is the intersection of
//    the two half-planes; this also clips round fallback discs correctly.)
// 6b. Slope widths (formats/SPEC.md "Slope widths"; Thöny et al. §3.3
//    corrects the same stretch). Step 6 measures the band in plan, so on a
//    slope a line is wider on the ground than its width. With the terrain
//    under P taken as the plane of gradient g = (dh/dx, dh/dy) (the
//    renderer's terrain triangle at the pixel), the ground distance of two
//    plan points u, v is |u - v|_G, the length of the plane's metric
//      <u, v>_G = u.v + (g.u)(g.v)     (G = I + g g^T, the first
//                                        fundamental form of z = h(x, y)).
//    A line's band on the ground is step 6 with every length in G. The
//    distance of d from the line through 0 along e is then
//      |cross(e, d)| / |e| * sqrt((1 + g.g) / (1 + (g.t)^2))
//      = |v| sqrt(1 + (g.n)^2 / (1 + (g.t)^2)),
//    v the plan offset, t = e / |e|, n the unit plan normal: |v| sqrt(1 +
//    (g.n)^2) (the plan perpendicular lifted onto the surface) only where
//    the line follows a contour (g.t = 0); elsewhere the lifted plan
//    perpendicular is not perpendicular to the lifted line on the surface.
//    Every piece of step 6 in G, with gam = 1 + g.g:
//      N(w) = hw (w - g (g.w) / gam) / sqrt(w.w - (g.w)^2 / gam), for a plan
//        edge normal w (a stored bevel vector): the G-unit normal of the
//        edge (G^-1 w normalised in G) times hw, on w's side. Its plan
//        offset from the edge is hw sqrt((1 + (g.t)^2) / gam) <= hw.
//      M(a, b) = hw^2 (a + b) / (hw^2 + <a, b>_G): the miter corner of two
//        G-normals a, b (both at G-distance hw from their edges).
//    round: t = clamp(<d,e>_G / <e,e>_G, 0, 1); covered <=> |d - t e|_G^2 <= hw^2.
//    miter: sa = sign(cross(e, Ca.bevel_out)) (+1: the stored bevels at a
//           are its left normals), sb = sign(cross(e, Cb.bevel_in));
//           ma = null(Ca.miter) ? N(sa Ca.bevel_out)
//                               : M(N(sa Ca.bevel_in), N(sa Ca.bevel_out)),
//           mb = null(Cb.miter) ? N(sb Cb.bevel_in)
//                               : M(N(sb Cb.bevel_in), N(sb Cb.bevel_out));
//           then the miter test of step 6 with these ma, mb and the discs
//           |d|_G^2 <= hw^2, |d - e|_G^2 <= hw^2 (line ends and round
//           fallbacks: ellipses in plan, circles on the ground). The ground
//           miter line (through ma) is not the plan one (through
//           Ca.miter), and the package's cells and boxes hold each
//           segment's plan quad: the neighbour's ground piece reaching past
//           the plan miter line onto this segment's side is this
//           segment's to cover. At a (not null(Ca.miter)), with w = sa
//           Ca.bevel_in (along the previous segment's left normal) and
//           t = left(w) (along its direction away from a), d is also
//           covered when cross(ma, d) cross(ma, t) >= 0 and
//           cross(Ca.miter, d) cross(Ca.miter, t) <= 0 (between the two
//           miter lines) and cross(t, d)^2 gam <= hw^2 (t.t + (g.t)^2) (in
//           the previous segment's ground strip); at b likewise with d - e,
//           mb, Cb.miter, w = sb Cb.bevel_out and t = -left(w) (the next
//           segment). No piece reaches farther from the segment in plan
//           than hw (round, bevel) or the longer of |Ca.miter|, |Cb.miter|
//           (miter): a cheap test rejects the rest first.
//    bevel: the bevel test of step 6 with n = N(Ca.bevel_out), the corner
//           triangles T(0, N(Ca.bevel_in), N(Ca.bevel_out), d) and
//           T(e, e + N(Cb.bevel_in), e + N(Cb.bevel_out), d), the discs in G.
//    Which corners are miters stays the package's (plan angles). The
//    outline side tests are half-planes bounded by the segments' own lines,
//    the same in any metric, and the clip ring is a plan ring: both stay.
//    |u|_G >= |u|: a round or bevel piece lies in the plan capsule of its
//    segment, which the package's cells and boxes of round and bevel
//    segments hold, and a miter piece in its plan quad but for the part the
//    neighbour covers: the culling of steps 1-3 stays exact. g = 0 (flat
//    ground) skips step 6b: step 6 exactly.
// 6c. Dashes (formats/SPEC.md "Dashed lines"; a layer with a `dash`
//    pattern in the metadata layer table, props.layer indexes it): a
//    "covered" segment covers P only if its along-line distance
//      s = D[s_vertex] + |e| * clamp(dot(d, e) / dot(e, e), 0, 1)
//    (D: the line's length from its first vertex to each vertex, computed
//    at load from line_vertices; in a corner's join region the clamp gives
//    the vertex's own D, so the phase is continuous across corners) lies in
//    an "on" interval [a, a + on) of r = s - P floor(s / P), P the period;
//    otherwise the result is "none" and the line's later segments are still
//    tested (the line covers the union of its segments' dashes).
// 7. Polygon leaf k: (poly, node, h0, hn) = cell_polys[cell_poly_range[cell].x + k].
//    inside = Q(node); if inside, for j in [h0, h0 + hn): (hp, hnode) =
//    cell_holes[j]; if Q(hnode): inside = false, stop. If inside, composite
//    poly_props[poly].rgba.
// 8. Quad-tree query Q(node): if P not in qt_node_box[node]: false. Loop:
//    (type, off) = qt_node[node]; type 0: node = the first of off+0..off+3
//    (SW, SE, NW, NE) whose box contains P (none: false); type 1: false;
//    type 2: true; type 3: even-odd over the leaf polygon:
//      (f, n) = qt_leaf_range[off]; inside = false; for each (u, v) in
//      qt_leaf_segments[f .. f+n): A = qt_leaf_vertices[u] - Pq,
//      B = qt_leaf_vertices[v] - Pq (quanta); if (A.y > 0) != (B.y > 0):
//        (L, H) = A.y > 0 ? (B, A) : (A, B);
//        if (H.x - L.x) * (-L.y) - (H.y - L.y) * (-L.x) > 0: inside = !inside.
//    The build evaluates this very rule exactly (CGAL) to classify leaves.
// ============================================================================
#include "prep/evaluate.hpp"

#include "compact_view.hpp"
#include "decal/layout.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <optional>

namespace prep {

namespace {

constexpr double kQ = decal::kQuantumMetres;

struct PointQ {
  double x, y;  // quanta relative to the origin
};

inline bool in_box(const ivec4& b, const PointQ& p) {
  return p.x >= double(b[0]) && p.x <= double(b[2]) && p.y >= double(b[1]) && p.y <= double(b[3]);
}
// The same with the box grown by `m` quanta (an empty box stays empty).
inline bool in_box(const ivec4& b, const PointQ& p, double m) {
  if (m <= 0) return in_box(b, p);
  if (b[0] > b[2]) return false;
  return p.x >= double(b[0]) - m && p.x <= double(b[2]) + m && p.y >= double(b[1]) - m &&
         p.y <= double(b[3]) + m;
}

struct V {
  double x, y;
};
inline V operator-(V a, V b) {
  return {a.x - b.x, a.y - b.y};
}
inline V operator+(V a, V b) {
  return {a.x + b.x, a.y + b.y};
}
inline V operator*(double s, V a) {
  return {s * a.x, s * a.y};
}
inline double dot(V a, V b) {
  return a.x * b.x + a.y * b.y;
}
inline double cross(V a, V b) {
  return a.x * b.y - a.y * b.x;
}
inline V vec(const float* f) {
  return {double(f[0]), double(f[1])};
}
inline bool null_vec(const float* f) {
  return f[0] == 0.f && f[1] == 0.f;
}

inline bool in_triangle(V a, V b, V c, V d) {
  const double c0 = cross(b - a, d - a), c1 = cross(c - b, d - b), c2 = cross(a - c, d - c);
  return (c0 >= 0 && c1 >= 0 && c2 >= 0) || (c0 <= 0 && c1 <= 0 && c2 <= 0);
}

bool leaf_polygon_covers(const StaticView& v, uint32_t range, const PointQ& p, EvalCounters* k) {
  const uvec2 r = v.qt_leaf_range[range];
  bool inside = false;
  for (uint32_t s = r[0]; s < r[0] + r[1]; ++s) {
    const ivec2& a = v.qt_leaf_vertices[v.qt_leaf_segments[s][0]];
    const ivec2& b = v.qt_leaf_vertices[v.qt_leaf_segments[s][1]];
    const V A{double(a[0]) - p.x, double(a[1]) - p.y}, B{double(b[0]) - p.x, double(b[1]) - p.y};
    if ((A.y > 0) == (B.y > 0)) continue;
    if (k) ++k->edge_tests;
    const V& L = A.y > 0 ? B : A;
    const V& H = A.y > 0 ? A : B;
    if ((H.x - L.x) * (-L.y) - (H.y - L.y) * (-L.x) > 0) inside = !inside;
  }
  return inside;
}

bool quadtree_covers(const StaticView& v, uint32_t node, const PointQ& p, EvalCounters* k) {
  if (k) ++k->qt_nodes;
  if (!in_box(v.qt_node_box[node], p)) return false;
  for (;;) {
    const ivec2 n = v.qt_node[node];
    switch (decal::QtNodeType(n[0])) {
      case decal::QtNodeType::internal: {
        bool found = false;
        for (int c = 0; c < 4 && !found; ++c) {
          const uint32_t ch = uint32_t(n[1] + c);
          if (k) ++k->qt_nodes;
          if (in_box(v.qt_node_box[ch], p)) {
            node = ch;
            found = true;
          }
        }
        if (!found) return false;
        break;
      }
      case decal::QtNodeType::outside: return false;
      case decal::QtNodeType::inside: return true;
      case decal::QtNodeType::partial: return leaf_polygon_covers(v, uint32_t(n[1]), p, k);
      default: return false;
    }
  }
}

// Step 6b: the plane of terrain gradient g, its metric and the corner
// pieces of the band measured in it.
struct SurfaceMetric {
  V g;
  double gam;  // 1 + g.g
  explicit SurfaceMetric(V grad) : g(grad), gam(1 + dot(grad, grad)) {}
  double gdot(V u, V v) const { return dot(u, v) + dot(g, u) * dot(g, v); }
  V normal(V w, double hw) const {  // N(w)
    const double gw = dot(g, w);
    return (hw / std::sqrt(dot(w, w) - gw * gw / gam)) * (w - (gw / gam) * g);
  }
  V miter(V a, V b, double hw) const {  // M(a, b)
    return (hw * hw / (hw * hw + gdot(a, b))) * (a + b);
  }
  // O(x, m, mg, w): x (from a miter vertex) lies in the neighbouring
  // segment's ground piece where it reaches past the plan miter line m onto
  // this segment's side; mg is the ground miter, w the neighbour's left
  // normal, t its unit direction away from the vertex (`ahead`: w is the
  // next segment's, t = -left(w); else the previous one's, t = left(w)).
  bool overhang(V x, V m, V mg, V w, double hw, bool ahead) const {
    const V t = ahead ? V{w.y, -w.x} : V{-w.y, w.x};  // |t| = |w|
    if (cross(mg, x) * cross(mg, t) < 0 || cross(m, x) * cross(m, t) > 0) return false;
    const double gt = dot(g, t), c = cross(t, x);
    return c * c * gam <= hw * hw * (dot(t, t) + gt * gt);
  }
};

// Step 6b: whether the segment's band, measured along the surface, covers
// d (metres from vertex a; e = b - a).
bool surface_band_covers(const SurfaceMetric& G, V e, V d, double hw, decal::CornerStyle style,
                         const decal::LineCorner& ca, const decal::LineCorner& cb) {
  const double hw2 = hw * hw;
  if (style != decal::CornerStyle::round) {
    // Every piece lies within hw (bevel) or the longer plan miter (miter)
    // of the segment in plan (|u|_G >= |u|; ground miter corners and the
    // overhangs lie in the plan corner's rhombus).
    const double ee = dot(e, e);
    const V r = d - (ee > 0 ? std::clamp(dot(d, e) / ee, 0.0, 1.0) : 0.0) * e;
    const double reach2 =
        style == decal::CornerStyle::miter
            ? std::max({hw2, dot(vec(ca.miter), vec(ca.miter)), dot(vec(cb.miter), vec(cb.miter))})
            : hw2;
    if (dot(r, r) > reach2) return false;
  }
  switch (style) {
    case decal::CornerStyle::round: {
      const double ee = G.gdot(e, e);
      const double t = ee > 0 ? std::clamp(G.gdot(d, e) / ee, 0.0, 1.0) : 0.0;
      const V r = d - t * e;
      return G.gdot(r, r) <= hw2;
    }
    case decal::CornerStyle::miter: {
      const bool na = null_vec(ca.miter), nb = null_vec(cb.miter);
      const double sa = cross(e, vec(ca.bevel_out)) >= 0 ? 1.0 : -1.0;
      const double sb = cross(e, vec(cb.bevel_in)) >= 0 ? 1.0 : -1.0;
      const V ma = na ? G.normal(sa * vec(ca.bevel_out), hw)
                      : G.miter(G.normal(sa * vec(ca.bevel_in), hw),
                                G.normal(sa * vec(ca.bevel_out), hw), hw);
      const V mb = nb ? G.normal(sb * vec(cb.bevel_in), hw)
                      : G.miter(G.normal(sb * vec(cb.bevel_in), hw),
                                G.normal(sb * vec(cb.bevel_out), hw), hw);
      return in_triangle(-1.0 * ma, e - mb, e + mb, d) || in_triangle(-1.0 * ma, e + mb, ma, d) ||
             (na && G.gdot(d, d) <= hw2) || (nb && G.gdot(d - e, d - e) <= hw2) ||
             (!na && G.overhang(d, vec(ca.miter), ma, sa * vec(ca.bevel_in), hw, false)) ||
             (!nb && G.overhang(d - e, vec(cb.miter), mb, sb * vec(cb.bevel_out), hw, true));
    }
    case decal::CornerStyle::bevel: {
      const V n = G.normal(vec(ca.bevel_out), hw);
      const double c = cross(e, n);
      if (c != 0) {
        const double sv = cross(e, d) / c, tv = cross(d, n) / c;
        if (tv >= 0 && tv <= 1 && std::fabs(sv) <= 1) return true;
      }
      if (null_vec(ca.bevel_in) ? G.gdot(d, d) <= hw2
                                : in_triangle({0, 0}, G.normal(vec(ca.bevel_in), hw), n, d))
        return true;
      return null_vec(cb.bevel_out) ? G.gdot(d - e, d - e) <= hw2
                                    : in_triangle(e, e + G.normal(vec(cb.bevel_in), hw),
                                                  e + G.normal(vec(cb.bevel_out), hw), d);
    }
  }
  return false;
}

// Outcome of the segment test (step 6): outside the band; in the band of a
// clipped outline but on the dropped side of its ring (no segment of that
// line can cover the point then); covered.
enum class SegmentHit { none, clipped, covered };

// The corner's vectors times `k` (a minimum width drawing the line wider).
decal::LineCorner scaled(const decal::LineCorner& c, double k) {
  decal::LineCorner out = c;
  for (float* v : {out.miter, out.bevel_in, out.bevel_out}) {
    v[0] = float(k * double(v[0]));
    v[1] = float(k * double(v[1]));
  }
  return out;
}

// `scale`: min_width_scale of the segment's line.
SegmentHit segment_test(const StaticView& v, uint32_t s, uint32_t e_idx, const PointQ& p,
                        EvalCounters* k, const SurfaceMetric* surface = nullptr,
                        double scale = 1.0) {
  const ivec2& ai = v.line_vertices[s];
  const ivec2& bi = v.line_vertices[e_idx];
  const decal::LineProps& pr = v.line_props[v.line_vertex_line[s]];
  const decal::LineCorner ca = scale == 1.0 ? v.line_corners[s] : scaled(v.line_corners[s], scale);
  const decal::LineCorner cb =
      scale == 1.0 ? v.line_corners[e_idx] : scaled(v.line_corners[e_idx], scale);
  const V e{double(bi[0] - ai[0]) * kQ, double(bi[1] - ai[1]) * kQ};
  const V d{(p.x - double(ai[0])) * kQ, (p.y - double(ai[1])) * kQ};
  const double hw = double(pr.half_width) * scale, hw2 = hw * hw;
  const auto style = decal::CornerStyle(pr.style & decal::kStyleCornerMask);
  const auto mode =
      decal::OutlineMode((pr.style & decal::kStyleOutlineMask) >> decal::kStyleOutlineShift);
  bool covered = false;
  switch (style) {
    case decal::CornerStyle::round: {
      const double ee = dot(e, e);
      const double t = ee > 0 ? std::clamp(dot(d, e) / ee, 0.0, 1.0) : 0.0;
      const V r = d - t * e;
      covered = dot(r, r) <= hw2;
      break;
    }
    case decal::CornerStyle::miter: {
      const bool na = null_vec(ca.miter), nb = null_vec(cb.miter);
      V ma = vec(ca.miter), mb = vec(cb.miter);
      if (na) {
        ma = vec(ca.bevel_out);
        if (cross(e, ma) < 0) ma = -1.0 * ma;
      }
      if (nb) {
        mb = vec(cb.bevel_in);
        if (cross(e, mb) < 0) mb = -1.0 * mb;
      }
      covered = in_triangle(-1.0 * ma, e - mb, e + mb, d) ||
                in_triangle(-1.0 * ma, e + mb, ma, d) || (na && dot(d, d) <= hw2) ||
                (nb && dot(d - e, d - e) <= hw2);
      break;
    }
    case decal::CornerStyle::bevel: {
      const V n = vec(ca.bevel_out);
      const double c = cross(e, n);
      if (c != 0) {
        const double sv = cross(e, d) / c, tv = cross(d, n) / c;
        covered = tv >= 0 && tv <= 1 && std::fabs(sv) <= 1;
      }
      if (!covered)
        covered = null_vec(ca.bevel_in)
                      ? dot(d, d) <= hw2
                      : in_triangle({0, 0}, vec(ca.bevel_in), vec(ca.bevel_out), d);
      if (!covered)
        covered = null_vec(cb.bevel_out)
                      ? dot(d - e, d - e) <= hw2
                      : in_triangle(e, e + vec(cb.bevel_in), e + vec(cb.bevel_out), d);
      break;
    }
  }
  // Step 6b replaces the plan band for a line measured along the terrain.
  if (surface) covered = surface_band_covers(*surface, e, d, hw, style, ca, cb);
  if (!covered) return SegmentHit::none;
  if (mode == decal::OutlineMode::normal) return SegmentHit::covered;
  if (pr.style & decal::kStyleClipBit) {
    // Clipped ring: the two-sided band, cut by the ring itself.
    const bool inside = quadtree_covers(v, pr.clip_node, p, k);
    return inside == ((pr.style & decal::kStyleClipInsideBit) != 0) ? SegmentHit::covered
                                                                    : SegmentHit::clipped;
  }
  const double K = mode == decal::OutlineMode::inset ? 1.0 : -1.0;
  if (K * cross(e, d) < 0) return SegmentHit::none;
  if (!null_vec(cb.bevel_out)) {
    const double o = cross(e, vec(cb.bevel_in)) >= 0 ? 1.0 : -1.0;
    if (K * o < 0 && K * dot(d - e, o * vec(cb.bevel_out)) < 0) return SegmentHit::none;
  }
  if (!null_vec(ca.bevel_in)) {
    const double o = cross(e, vec(ca.bevel_out)) >= 0 ? 1.0 : -1.0;
    if (K * o < 0 && K * dot(d, o * vec(ca.bevel_in)) < 0) return SegmentHit::none;
  }
  return SegmentHit::covered;
}

// Step 6c: whether the dash pattern of segment (s, e)'s layer is "on" at
// the point (true for a solid layer).
bool dash_covers(const StaticView& v, uint32_t s, uint32_t e_idx, uint32_t line, const PointQ& p) {
  if (!v.dashes) return true;
  const std::span<const double> pattern = v.dashes->table.of(v.line_props[line].layer);
  if (pattern.empty()) return true;
  const ivec2& ai = v.line_vertices[s];
  const ivec2& bi = v.line_vertices[e_idx];
  const V e{double(bi[0] - ai[0]) * kQ, double(bi[1] - ai[1]) * kQ};
  const V d{(p.x - double(ai[0])) * kQ, (p.y - double(ai[1])) * kQ};
  const double ee = dot(e, e);
  const double t = ee > 0 ? std::clamp(dot(d, e) / ee, 0.0, 1.0) : 0.0;
  return dash_on(pattern, v.dashes->vertex_distance[s] + t * std::sqrt(ee));
}

struct Compositor {
  EvalSample& out;
  std::span<const uint8_t> unlit;  // per layer; empty: every layer lit
  // Returns true once opaque.
  bool add(uint32_t rgba, uint32_t layer) {
    const double a = double((rgba >> 24) & 0xffu) / 255.0;
    const double w = (1.0 - out.rgba[3]) * a;
    const bool flat = !unlit.empty() && unlit[std::min<size_t>(layer, unlit.size() - 1)];
    for (int ch = 0; ch < 3; ++ch) {
      const float c = float(w * double((rgba >> (8 * ch)) & 0xffu) / 255.0);
      out.rgba[ch] += c;
      if (flat) out.unlit_rgb[ch] += c;
    }
    out.rgba[3] += float(w);
    return out.rgba[3] >= 0.999f;
  }
};

// Stack-less traversal of one cell's implicit BVH (Eq. 4.5-4.7) as a cursor:
// next() returns the next leaf whose box holds P, in leaf order (which is
// drawing order), or kNoLeaf once the traversal has ended. Leaves past the
// cell's list (padding slots) are skipped.
constexpr uint32_t kNoLeaf = ~0u;

class BvhCursor {
 public:
  BvhCursor() = default;
  BvhCursor(const uvec4& range, uint32_t leaves, std::span<const ivec4> boxes, const PointQ& p,
            EvalCounters* k, double margin = 0)
      : boxes_(boxes),
        p_(p),
        margin_(margin),
        k_(k),
        first_(range[0]),
        internal_(range[2]),
        leaves_(leaves),
        done_(range[1] == 0) {}

  uint32_t next() {
    while (!done_) {
      if (k_) ++k_->bvh_nodes;
      if (in_box(boxes_[first_ + i_], p_, margin_)) {
        if (i_ < internal_) {
          i_ = 2 * i_ + 1;
          continue;
        }
        const uint32_t leaf = i_ - internal_;
        climb();
        if (leaf < leaves_) return leaf;
        continue;
      }
      climb();
    }
    return kNoLeaf;
  }

 private:
  // Up from right children, then to the right sibling; the root ends it.
  void climb() {
    while (i_ > 0 && (i_ & 1u) == 0) i_ = (i_ - 1) / 2;
    if (i_ == 0)
      done_ = true;
    else
      ++i_;
  }

  std::span<const ivec4> boxes_;
  PointQ p_{0, 0};
  double margin_ = 0;  // quanta the boxes are grown by
  EvalCounters* k_ = nullptr;
  uint32_t first_ = 0, internal_ = 0, leaves_ = 0, i_ = 0;
  bool done_ = true;
};

bool cell_of(const GridParams& g, const PointQ& p, uint32_t& cell) {
  if (g.nx == 0 || g.ny == 0) return false;
  const double fx = std::floor((p.x - double(g.origin_x)) / double(g.cell_w));
  const double fy = std::floor((p.y - double(g.origin_y)) / double(g.cell_h));
  if (!(fx >= 0 && fy >= 0 && fx < double(g.nx) && fy < double(g.ny))) return false;
  cell = uint32_t(fx) + g.nx * uint32_t(fy);
  return true;
}

}  // namespace

StaticView view_of(const DecalModel& m) {
  StaticView v;
  v.grid = m.grid;
#define PREP_FROM_MODEL(T, name) v.name = m.name;
  PREP_STATIC_VIEW_BLOBS(PREP_FROM_MODEL)
#undef PREP_FROM_MODEL
  CompactBlobs c;
#define PREP_COMPACT_FROM_MODEL(T, name) c.name = m.name;
  PREP_COMPACT_BLOBS(PREP_COMPACT_FROM_MODEL)
#undef PREP_COMPACT_FROM_MODEL
  decode_compact(c, v);
  return v;
}

void decode_compact(const CompactBlobs& c, StaticView& v) {
  namespace L = decal::layout;
  static_assert(std::is_same_v<L::u2, uvec2> && std::is_same_v<L::u4, uvec4>);
  struct Decoded {
    std::vector<uvec2> seg_range, poly_range, leaf_range, leaf_segments;
    std::vector<uvec4> line_bvh, poly_bvh, cell_polys;
    std::vector<ivec4> line_boxes, poly_boxes;
  };
  const L::CellGrid cg{v.grid.origin_x, v.grid.origin_y, v.grid.cell_w, v.grid.cell_h, v.grid.nx};
  auto d = std::make_shared<Decoded>();
  // One kind's per-cell firsts and 16-bit boxes into its ranges, BVH ranges
  // and boxes.
  auto cells = [&](std::span<const uvec2> first, std::span<const uvec2> box16,
                   std::vector<uvec2>& range, std::vector<uvec4>& bvh, std::vector<ivec4>& boxes,
                   std::span<const uvec2>& vrange, std::span<const uvec4>& vbvh,
                   std::span<const ivec4>& vboxes) {
    if (first.empty()) return;
    L::decode_cells(first, range, bvh);
    boxes = L::decode_boxes16(first, box16, cg);
    vrange = range;
    vbvh = bvh;
    vboxes = boxes;
  };
  cells(c.cell_line_first, c.line_bvh_box16, d->seg_range, d->line_bvh, d->line_boxes,
        v.cell_segment_range, v.line_bvh_range, v.line_bvh_box);
  cells(c.cell_poly_first, c.poly_bvh_box16, d->poly_range, d->poly_bvh, d->poly_boxes,
        v.cell_poly_range, v.poly_bvh_range, v.poly_bvh_box);
  if (!c.qt_leaf_loop_range.empty() || !c.qt_leaf_loops.empty()) {
    L::decode_leaves(c.qt_leaf_loop_range, c.qt_leaf_loops, d->leaf_range, d->leaf_segments);
    v.qt_leaf_range = d->leaf_range;
    v.qt_leaf_segments = d->leaf_segments;
  }
  if (!c.cell_poly_entries.empty()) {
    L::decode_poly_entries(c.cell_poly_entries, c.cell_poly_holes, d->cell_polys);
    v.cell_polys = d->cell_polys;
  }
  v.storage = std::move(d);
}

std::vector<DrawRun> draw_runs(const StaticView& v) {
  struct Item {
    uint64_t rank;
    DrawRun::Kind kind;
    uint32_t order;
  };
  std::vector<Item> items;
  items.reserve(v.line_props.size() + v.poly_props.size());
  for (const decal::LineProps& l : v.line_props)
    items.push_back({l.order, DrawRun::Kind::lines, l.order});
  for (const decal::PolyProps& g : v.poly_props)
    if (g.exterior < 0)
      items.push_back({g.order + v.polygon_rank_bias, DrawRun::Kind::polygons, g.order});
  // Ties (none in a valid package) put the line first, as evaluate() does.
  std::sort(items.begin(), items.end(), [](const Item& a, const Item& b) {
    return a.rank != b.rank ? a.rank < b.rank : a.kind < b.kind;
  });
  std::vector<DrawRun> runs;
  for (const Item& it : items) {
    if (runs.empty() || runs.back().kind != it.kind)
      runs.push_back({it.kind, it.order, it.order + 1});
    else
      runs.back().hi = std::max(runs.back().hi, it.order + 1);
  }
  return runs;
}

bool polygon_ring_covers(const StaticView& v, uint32_t poly, double x, double y) {
  return quadtree_covers(v, v.poly_root_node[poly], {x / kQ, y / kQ}, nullptr);
}

bool segment_covers(const StaticView& v, uint32_t start, uint32_t end, double x, double y) {
  return segment_test(v, start, end, {x / kQ, y / kQ}, nullptr) == SegmentHit::covered;
}

EvalSample evaluate(const StaticView& v, double x, double y, EvalCounters* k) {
  return evaluate(v, x, y, SurfaceSlope{}, k);
}

EvalSample evaluate(const StaticView& v, double x, double y, const SurfaceSlope& slope,
                    EvalCounters* k) {
  return evaluate(v, x, y, EvalPixel{slope}, k);
}

double min_width_scale(const StaticView& v, uint32_t line, const EvalPixel& px) {
  if (px.min_width_px.empty() || !(px.min_width_pixel_m > 0)) return 1.0;
  const decal::LineProps& pr = v.line_props[line];
  const float n = px.min_width_px[std::min<size_t>(pr.layer, px.min_width_px.size() - 1)];
  if (!(n > 0)) return 1.0;
  const auto mode =
      decal::OutlineMode((pr.style & decal::kStyleOutlineMask) >> decal::kStyleOutlineShift);
  const double want = double(n) * (mode == decal::OutlineMode::normal ? 0.5 : 1.0) *
                      std::min(px.pixel_m, px.min_width_pixel_m);
  const double hw = pr.half_width;
  return want > hw && hw > 0 ? want / hw : 1.0;
}

EvalSample evaluate(const StaticView& v, double x, double y, const EvalPixel& px, EvalCounters* k) {
  const SurfaceSlope& slope = px.slope;
  const std::span<const uint8_t> unlit = px.unlit;
  EvalSample out;
  // Step 6b applies to the lines of the flagged layers where the ground is
  // not level.
  const std::optional<SurfaceMetric> surface =
      (slope.gx != 0 || slope.gy != 0) && !slope.layers.empty()
          ? std::optional<SurfaceMetric>(SurfaceMetric({slope.gx, slope.gy}))
          : std::nullopt;
  auto surface_of = [&](uint32_t line) -> const SurfaceMetric* {
    const uint32_t layer = v.line_props[line].layer;
    return surface && slope.layers[std::min<size_t>(layer, slope.layers.size() - 1)] ? &*surface
                                                                                     : nullptr;
  };
  const PointQ p{x / kQ, y / kQ};
  uint32_t cell;
  if (!cell_of(v.grid, p, cell)) return out;
  Compositor comp{out, unlit};
  // Step 3/4: two front-to-back streams, one per BVH, merged by rank.
  const uvec2 lines = v.line_bvh_range.empty() ? uvec2{0, 0} : v.cell_segment_range[cell];
  const uvec2 polys = v.poly_bvh_range.empty() ? uvec2{0, 0} : v.cell_poly_range[cell];
  BvhCursor line_cursor, poly_cursor;
  if (!v.line_bvh_range.empty())
    line_cursor = {v.line_bvh_range[cell],   lines[1], v.line_bvh_box, p, k,
                   px.line_box_margin_m / kQ};
  if (!v.poly_bvh_range.empty())
    poly_cursor = {v.poly_bvh_range[cell], polys[1], v.poly_bvh_box, p, k};
  auto line_of_leaf = [&](uint32_t leaf) {
    return v.line_vertex_line[v.cell_segments[lines[0] + leaf][0]];
  };
  auto line_rank = [&](uint32_t leaf) { return uint64_t(v.line_props[line_of_leaf(leaf)].order); };
  auto poly_rank = [&](uint32_t leaf) {
    return uint64_t(v.poly_props[v.cell_polys[polys[0] + leaf][0]].order) + v.polygon_rank_bias;
  };
  int64_t last_line = -1;
  // Line leaf (step 5): true once opaque.
  auto line_leaf = [&](uint32_t leaf) {
    const uvec2 seg = v.cell_segments[lines[0] + leaf];
    const uint32_t line = v.line_vertex_line[seg[0]];
    if (int64_t(line) == last_line) return false;
    if (k) ++k->segment_tests;
    const SegmentHit hit =
        segment_test(v, seg[0], seg[1], p, k, surface_of(line), min_width_scale(v, line, px));
    if (hit == SegmentHit::none) return false;
    if (hit == SegmentHit::covered && !dash_covers(v, seg[0], seg[1], line, p)) return false;
    last_line = line;  // decided: covered, or clipped away for every segment
    if (hit == SegmentHit::clipped) return false;
    if (!out.line_covered) out.top_line = int32_t(line);
    out.line_covered = true;
    return comp.add(v.line_props[line].rgba, v.line_props[line].layer);
  };
  // Polygon leaf (step 7): true once opaque.
  auto poly_leaf = [&](uint32_t leaf) {
    const uvec4 cp = v.cell_polys[polys[0] + leaf];
    if (!quadtree_covers(v, cp[1], p, k)) return false;
    for (uint32_t j = cp[2]; j < cp[2] + cp[3]; ++j)
      if (quadtree_covers(v, v.cell_holes[j][1], p, k)) return false;
    if (!out.polygon_covered) out.top_polygon = int32_t(cp[0]);
    out.polygon_covered = true;
    return comp.add(v.poly_props[cp[0]].rgba, v.poly_props[cp[0]].layer);
  };
  uint32_t l = line_cursor.next(), g = poly_cursor.next();
  while (l != kNoLeaf || g != kNoLeaf) {
    if (g == kNoLeaf || (l != kNoLeaf && line_rank(l) < poly_rank(g))) {
      if (line_leaf(l)) break;
      l = line_cursor.next();
    } else {
      if (poly_leaf(g)) break;
      g = poly_cursor.next();
    }
  }
  return out;
}

std::vector<float> render_topdown(const StaticView& v, const Extent& ex, uint32_t w, uint32_t h) {
  std::vector<float> img(size_t(w) * h * 4, 0.f);
  const double px = (ex.xmax - ex.xmin) / w, py = (ex.ymax - ex.ymin) / h;
  tbb::parallel_for(uint32_t(0), h, [&](uint32_t j) {
    for (uint32_t i = 0; i < w; ++i) {
      const EvalSample s = evaluate(v, ex.xmin + (i + 0.5) * px, ex.ymax - (j + 0.5) * py);
      float* o = &img[(size_t(j) * w + i) * 4];
      const float a = s.rgba[3];
      for (int c = 0; c < 3; ++c) o[c] = a > 0 ? std::min(1.f, s.rgba[c] / a) : 0.f;
      o[3] = a;
    }
  });
  return img;
}

std::vector<uint8_t> to_rgba8(std::span<const float> rgba) {
  std::vector<uint8_t> out(rgba.size());
  for (size_t i = 0; i < rgba.size(); ++i)
    out[i] = uint8_t(std::lround(std::clamp(double(rgba[i]), 0.0, 1.0) * 255.0));
  return out;
}

}  // namespace prep
