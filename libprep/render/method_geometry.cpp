// The planar geometry of the volume and texture methods
// (detail/method_geometry.hpp): polygons with holes through CGAL's
// constrained Delaunay triangulation, static lines as the convex pieces of
// the evaluator's segment test. The only file of prep_render that includes
// CGAL.
#include "detail/method_geometry.hpp"

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <map>
#include <numbers>
#include <set>
#include <span>
#include <utility>

namespace prep::render::detail {

namespace {

constexpr double kQ = decal::kQuantumMetres;

// Largest distance between a round end's polygon and its circle, metres.
constexpr double kDiscTolerance = 0.01;

using Piece = std::vector<P2d>;  // convex, counter-clockwise

P2d operator+(P2d a, P2d b) {
  return {a[0] + b[0], a[1] + b[1]};
}
P2d operator-(P2d a, P2d b) {
  return {a[0] - b[0], a[1] - b[1]};
}
P2d operator*(double s, P2d a) {
  return {s * a[0], s * a[1]};
}
double dot(P2d a, P2d b) {
  return a[0] * b[0] + a[1] * b[1];
}
double cross(P2d a, P2d b) {
  return a[0] * b[1] - a[1] * b[0];
}
P2d vec(const float* f) {
  return {double(f[0]), double(f[1])};
}
bool null_vec(const float* f) {
  return f[0] == 0.f && f[1] == 0.f;
}
P2d metres(const ivec2& v) {
  return {double(v[0]) * kQ, double(v[1]) * kQ};
}

double signed_area(const Piece& p) {
  double a = 0;
  for (size_t i = 0; i < p.size(); ++i) a += cross(p[i], p[(i + 1) % p.size()]);
  return 0.5 * a;
}

// Counter-clockwise; empty when degenerate.
Piece ccw(Piece p) {
  const double a = signed_area(p);
  if (!(std::abs(a) > 1e-12)) return {};
  if (a < 0) std::reverse(p.begin(), p.end());
  return p;
}

// Sutherland–Hodgman against one half-plane: keeps dot(n, x) >= c.
Piece clip_halfplane(const Piece& p, P2d n, double c) {
  Piece out;
  if (p.empty()) return out;
  for (size_t i = 0; i < p.size(); ++i) {
    const P2d& a = p[i];
    const P2d& b = p[(i + 1) % p.size()];
    const double da = dot(n, a) - c, db = dot(n, b) - c;
    if (da >= 0) out.push_back(a);
    if ((da >= 0) != (db >= 0)) out.push_back(a + (da / (da - db)) * (b - a));
  }
  return out.size() >= 3 ? out : Piece{};
}

Piece clip_box(Piece p, const Extent& e) {
  p = clip_halfplane(p, {1, 0}, e.xmin);
  p = clip_halfplane(p, {-1, 0}, -e.xmax);
  p = clip_halfplane(p, {0, 1}, e.ymin);
  return clip_halfplane(p, {0, -1}, -e.ymax);
}

// Convex piece ∩ counter-clockwise triangle.
Piece clip_triangle(Piece p, const std::array<P2d, 3>& t) {
  for (int i = 0; i < 3 && !p.empty(); ++i) {
    const P2d d = t[(i + 1) % 3] - t[i];
    const P2d n{-d[1], d[0]};
    p = clip_halfplane(p, n, dot(n, t[i]));
  }
  return p;
}

Extent box_of(const Piece& p) {
  Extent e{INFINITY, INFINITY, -INFINITY, -INFINITY};
  for (const P2d& v : p) {
    e.xmin = std::min(e.xmin, v[0]);
    e.ymin = std::min(e.ymin, v[1]);
    e.xmax = std::max(e.xmax, v[0]);
    e.ymax = std::max(e.ymax, v[1]);
  }
  return e;
}
bool boxes_meet(const Extent& a, const Extent& b) {
  return a.xmin <= b.xmax && b.xmin <= a.xmax && a.ymin <= b.ymax && b.ymin <= a.ymax;
}

// A round end: a polygon whose edges cross the circle of radius r, so that
// it stays within kDiscTolerance of it.
Piece disc(P2d c, double r) {
  if (!(r > 0)) return {};
  const double cosine = std::clamp(1.0 - kDiscTolerance / r, -1.0, 1.0);
  const int n = std::clamp(int(std::ceil(std::numbers::pi / std::acos(cosine))), 8, 96);
  const double rv = r * 2.0 / (1.0 + std::cos(std::numbers::pi / n));
  Piece p;
  for (int k = 0; k < n; ++k) {
    const double a = 2 * std::numbers::pi * k / n;
    p.push_back({c[0] + rv * std::cos(a), c[1] + rv * std::sin(a)});
  }
  return p;
}

// --- CGAL: constrained Delaunay triangulation with nesting depths (the
// domain marking of CGAL's "polygon with holes" example).
struct FaceInfo {
  int nesting = -1;
};
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_2<Kernel>;
using Fbb = CGAL::Triangulation_face_base_with_info_2<FaceInfo, Kernel>;
using Fb = CGAL::Constrained_triangulation_face_base_2<Kernel, Fbb>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<Kernel, Tds, CGAL::Exact_predicates_tag>;

void mark_domains(Cdt& cdt) {
  for (Cdt::Face_handle f : cdt.all_face_handles()) f->info().nesting = -1;
  std::deque<std::pair<Cdt::Face_handle, int>> border{{cdt.infinite_face(), 0}};
  while (!border.empty()) {
    auto [start, level] = border.front();
    border.pop_front();
    if (start->info().nesting != -1) continue;
    std::deque<Cdt::Face_handle> queue{start};
    while (!queue.empty()) {
      Cdt::Face_handle f = queue.front();
      queue.pop_front();
      if (f->info().nesting != -1) continue;
      f->info().nesting = level;
      for (int i = 0; i < 3; ++i) {
        Cdt::Face_handle n = f->neighbor(i);
        if (n->info().nesting != -1) continue;
        if (cdt.is_constrained({f, i}))
          border.emplace_back(n, level + 1);
        else
          queue.push_back(n);
      }
    }
  }
}

using QEdge = std::array<ivec2, 2>;

// The ring edges of the polygon whose quad-tree starts at `root`: leaf
// segments with both ends in the root box, which is the ring's box (closing
// segments end on the frame one quantum outside it), each once.
void ring_edges(const StaticView& v, uint32_t root, std::vector<QEdge>& out) {
  if (root >= v.qt_node.size()) return;
  const ivec4 rb = v.qt_node_box[root];
  auto inside = [&](const ivec2& p) {
    return p[0] >= rb[0] && p[0] <= rb[2] && p[1] >= rb[1] && p[1] <= rb[3];
  };
  auto key = [](const ivec2& p) { return (uint64_t(uint32_t(p[0])) << 32) | uint32_t(p[1]); };
  std::set<std::pair<uint64_t, uint64_t>> seen;
  std::vector<uint32_t> stack{root};
  while (!stack.empty()) {
    const uint32_t n = stack.back();
    stack.pop_back();
    const ivec2 node = v.qt_node[n];
    if (node[0] == int32_t(decal::QtNodeType::internal)) {
      for (uint32_t c = 0; c < 4; ++c) stack.push_back(uint32_t(node[1]) + c);
    } else if (node[0] == int32_t(decal::QtNodeType::partial)) {
      const uvec2 range = v.qt_leaf_range[uint32_t(node[1])];
      for (uint32_t s = range[0]; s < range[0] + range[1]; ++s) {
        const ivec2& a = v.qt_leaf_vertices[v.qt_leaf_segments[s][0]];
        const ivec2& b = v.qt_leaf_vertices[v.qt_leaf_segments[s][1]];
        if (!inside(a) || !inside(b) || a == b) continue;
        const uint64_t ka = key(a), kb = key(b);
        const std::pair<uint64_t, uint64_t> k{std::min(ka, kb), std::max(ka, kb)};
        if (seen.insert(k).second) out.push_back({a, b});
      }
    }
  }
}

// Triangulates the constraint edges (quanta) and keeps the faces whose
// nesting depth `keep` accepts; with `boundary`, also the edges between a
// kept face and one that is not (interior on the left).
template <class Keep>
void triangulate(const std::vector<QEdge>& edges, Keep keep, std::vector<std::array<P2d, 3>>& tris,
                 std::vector<std::array<P2d, 2>>* boundary) {
  Cdt cdt;
  for (const QEdge& e : edges)
    cdt.insert_constraint(Cdt::Point(double(e[0][0]), double(e[0][1])),
                          Cdt::Point(double(e[1][0]), double(e[1][1])));
  if (cdt.dimension() != 2) return;  // no area: no edges, or all on one line
  mark_domains(cdt);
  auto pt = [](const Cdt::Point& p) { return P2d{p.x() * kQ, p.y() * kQ}; };
  auto kept = [&](Cdt::Face_handle f) { return !cdt.is_infinite(f) && keep(f->info().nesting); };
  for (Cdt::Face_handle f : cdt.finite_face_handles()) {
    if (!kept(f)) continue;
    tris.push_back(
        {pt(f->vertex(0)->point()), pt(f->vertex(1)->point()), pt(f->vertex(2)->point())});
    if (!boundary) continue;
    for (int i = 0; i < 3; ++i)
      if (!kept(f->neighbor(i)))
        boundary->push_back(
            {pt(f->vertex(Cdt::ccw(i))->point()), pt(f->vertex(Cdt::cw(i))->point())});
  }
}

class Builder {
 public:
  Builder(const StaticView& view, const std::optional<Extent>& clip) : v_(view), clip_(clip) {}

  void polygon(uint32_t p, const std::vector<uint32_t>& holes) {
    std::vector<QEdge> edges;
    ring_edges(v_, v_.poly_root_node[p], edges);
    for (uint32_t h : holes) ring_edges(v_, v_.poly_root_node[h], edges);
    std::vector<std::array<P2d, 3>> tris;
    std::vector<std::array<P2d, 2>> boundary;
    triangulate(
        edges, [](int n) { return n % 2 == 1; }, tris, clip_ ? nullptr : &boundary);
    MethodFeature f = begin(v_.poly_props[p].rgba, false, v_.poly_props[p].layer);
    f.rank = uint32_t(v_.poly_props[p].order + v_.polygon_rank_bias);
    if (clip_) {
      for (const auto& t : tris) add_piece(f, clip_box({t[0], t[1], t[2]}, *clip_));
    } else {
      for (const auto& t : tris) add_triangle(f, t);
      for (const auto& e : boundary) out_.edges.push_back(e);
      f.edges = uint32_t(out_.edges.size()) - f.first_edge;
    }
    finish(f);
  }

  void line(uint32_t l, std::vector<uvec2>& segments) {
    const decal::LineProps& props = v_.line_props[l];
    const double hw = props.half_width;
    const uint32_t corner = props.style & decal::kStyleCornerMask;
    const uint32_t mode = (props.style & decal::kStyleOutlineMask) >> decal::kStyleOutlineShift;
    const bool clipped = (props.style & decal::kStyleClipBit) != 0;
    // Corner pieces are shared by the segments that meet there unless each
    // segment cuts its own with half-planes (or with its dashes).
    const std::span<const double> dash =
        v_.dashes ? v_.dashes->table.of(props.layer) : std::span<const double>{};
    const bool share = (mode == 0 || clipped) && dash.empty();
    std::set<uint64_t> corners;
    std::vector<Piece> pieces;
    auto corner_once = [&](uint32_t vertex, uint32_t kind) {
      return !share || corners.insert(uint64_t(vertex) * 2 + kind).second;
    };
    std::sort(segments.begin(), segments.end());
    segments.erase(std::unique(segments.begin(), segments.end()), segments.end());
    for (const uvec2& seg : segments) {
      const uint32_t s = seg[0], en = seg[1];
      const P2d a = metres(v_.line_vertices[s]), b = metres(v_.line_vertices[en]);
      const P2d e = b - a;
      const decal::LineCorner& ca = v_.line_corners[s];
      const decal::LineCorner& cb = v_.line_corners[en];
      std::vector<Piece> seg_pieces;
      const double len = std::sqrt(dot(e, e));
      if (corner == uint32_t(decal::CornerStyle::round)) {
        if (len > 0) {
          const P2d n = (hw / len) * P2d{-e[1], e[0]};
          seg_pieces.push_back({a - n, b - n, b + n, a + n});
        }
        if (corner_once(s, 0)) seg_pieces.push_back(disc(a, hw));
        if (corner_once(en, 0)) seg_pieces.push_back(disc(b, hw));
      } else if (corner == uint32_t(decal::CornerStyle::miter)) {
        P2d ma = vec(ca.miter), mb = vec(cb.miter);
        if (null_vec(ca.miter))
          ma = cross(e, vec(ca.bevel_out)) < 0 ? -1.0 * vec(ca.bevel_out) : vec(ca.bevel_out);
        if (null_vec(cb.miter))
          mb = cross(e, vec(cb.bevel_in)) < 0 ? -1.0 * vec(cb.bevel_in) : vec(cb.bevel_in);
        Piece quad{a - ma, b - mb, b + mb, a + ma};
        if (std::abs(signed_area(quad)) > 0 && is_convex(quad)) {
          seg_pieces.push_back(quad);
        } else {
          seg_pieces.push_back({a - ma, b - mb, b + mb});
          seg_pieces.push_back({a - ma, b + mb, a + ma});
        }
        if (null_vec(ca.miter) && corner_once(s, 0)) seg_pieces.push_back(disc(a, hw));
        if (null_vec(cb.miter) && corner_once(en, 0)) seg_pieces.push_back(disc(b, hw));
      } else {
        const P2d n = vec(ca.bevel_out);
        seg_pieces.push_back({a - n, b - n, b + n, a + n});
        if (null_vec(ca.bevel_in)) {
          if (corner_once(s, 0)) seg_pieces.push_back(disc(a, hw));
        } else if (corner_once(s, 1)) {
          seg_pieces.push_back({a, a + vec(ca.bevel_in), a + vec(ca.bevel_out)});
        }
        if (null_vec(cb.bevel_out)) {
          if (corner_once(en, 0)) seg_pieces.push_back(disc(b, hw));
        } else if (corner_once(en, 1)) {
          seg_pieces.push_back({b, b + vec(cb.bevel_in), b + vec(cb.bevel_out)});
        }
      }
      if (mode != 0 && !clipped) {
        // Open inset/offset lines: the evaluator's half-planes (step 6).
        const double K = mode == 1 ? 1.0 : -1.0;
        for (Piece& p : seg_pieces) {
          p = ccw(std::move(p));
          const P2d n = K * P2d{-e[1], e[0]};
          p = clip_halfplane(p, n, dot(n, a));
          if (!null_vec(cb.bevel_out)) {
            const double o = cross(e, vec(cb.bevel_in)) >= 0 ? 1.0 : -1.0;
            if (K * o < 0) {
              const P2d nb = (K * o) * vec(cb.bevel_out);
              p = clip_halfplane(p, nb, dot(nb, b));
            }
          }
          if (!null_vec(ca.bevel_in)) {
            const double o = cross(e, vec(ca.bevel_out)) >= 0 ? 1.0 : -1.0;
            if (K * o < 0) {
              const P2d na = (K * o) * vec(ca.bevel_in);
              p = clip_halfplane(p, na, dot(na, a));
            }
          }
        }
      }
      if (!dash.empty())
        seg_pieces =
            dash_pieces(std::move(seg_pieces), a, e, len, v_.dashes->vertex_distance[s], dash);
      for (Piece& p : seg_pieces) pieces.push_back(std::move(p));
    }
    if (clipped) pieces = clip_to_ring(props, hw, std::move(pieces));
    MethodFeature f = begin(props.rgba, true, props.layer);
    f.rank = props.order;
    for (Piece& p : pieces) {
      p = ccw(std::move(p));
      add_piece(f, clip_ ? clip_box(std::move(p), *clip_) : std::move(p));
    }
    finish(f);
  }

  MethodGeometry take() { return std::move(out_); }

 private:
  // Dashes (evaluator step 6b, formats/SPEC.md "Dashed lines"): the parts
  // of segment (a, a + e)'s pieces where its along-line distance is on:
  // d0 + the projection on the segment, clamped (before a: d0, past b:
  // d0 + len), so the slabs of the "on" intervals between a and b and the
  // pieces' parts beyond either end when that end's distance is on.
  static std::vector<Piece> dash_pieces(std::vector<Piece> pieces, const P2d& a, const P2d& e,
                                        double len, double d0, std::span<const double> dash) {
    std::vector<Piece> out;
    if (!(len > 0)) {
      if (dash_on(dash, d0)) return pieces;
      return out;
    }
    const P2d u = (1 / len) * e;
    const double ua = dot(u, a);
    // Keeps the part of p whose projection from a lies in [lo, hi].
    auto keep = [&](const Piece& p, double lo, double hi) {
      Piece q = p;
      if (std::isfinite(lo)) q = clip_halfplane(q, u, ua + lo);
      if (std::isfinite(hi)) q = clip_halfplane(q, -1.0 * u, -(ua + hi));
      if (q.size() >= 3) out.push_back(std::move(q));
    };
    double period = 0;
    for (double x : dash) period += x;
    for (Piece& p : pieces) {
      p = ccw(std::move(p));
      if (dash_on(dash, d0)) keep(p, -INFINITY, 0);
      if (dash_on(dash, d0 + len)) keep(p, len, INFINITY);
      double start = period * std::floor(d0 / period);
      for (size_t i = 0; start < d0 + len; i = (i + 1) % dash.size()) {
        const double lo = std::max(start, d0), hi = std::min(start + dash[i], d0 + len);
        if (i % 2 == 0 && lo < hi) keep(p, lo - d0, hi - d0);
        start += dash[i];
      }
    }
    return out;
  }

  static bool is_convex(const Piece& p) {
    int sign = 0;
    for (size_t i = 0; i < p.size(); ++i) {
      const double c =
          cross(p[(i + 1) % p.size()] - p[i], p[(i + 2) % p.size()] - p[(i + 1) % p.size()]);
      const int s = (c > 0) - (c < 0);
      if (s == 0) continue;
      if (sign != 0 && s != sign) return false;
      sign = s;
    }
    return true;
  }

  // Clipped outlines (closed inset/offset rings): the band cut by the
  // line's own ring, inside or outside (evaluator step 6): every piece
  // intersected with the triangles of the ring's side, within a frame around
  // the ring wider than the band.
  std::vector<Piece> clip_to_ring(const decal::LineProps& props, double hw,
                                  std::vector<Piece> pieces) {
    const bool inside = (props.style & decal::kStyleClipInsideBit) != 0;
    std::vector<QEdge> edges;
    ring_edges(v_, props.clip_node, edges);
    if (edges.empty()) return {};
    const ivec4 rb = v_.qt_node_box[props.clip_node];
    const int32_t m = int32_t(std::ceil((4 * hw + 1.0) / kQ));
    const ivec2 c0{rb[0] - m, rb[1] - m}, c1{rb[2] + m, rb[1] - m}, c2{rb[2] + m, rb[3] + m},
        c3{rb[0] - m, rb[3] + m};
    if (!inside) {
      edges.push_back({c0, c1});
      edges.push_back({c1, c2});
      edges.push_back({c2, c3});
      edges.push_back({c3, c0});
    }
    std::vector<std::array<P2d, 3>> tris;
    // Inside: odd depth (the ring alone). Outside: depth 1 is between the
    // frame and the ring.
    triangulate(
        edges, [inside](int n) { return inside ? n % 2 == 1 : n == 1; }, tris, nullptr);
    std::vector<Extent> boxes;
    for (auto& t : tris) {
      if (cross(t[1] - t[0], t[2] - t[0]) < 0) std::swap(t[1], t[2]);
      boxes.push_back(box_of({t[0], t[1], t[2]}));
    }
    std::vector<Piece> out;
    for (Piece& p : pieces) {
      p = ccw(std::move(p));
      if (p.empty()) continue;
      const Extent pb = box_of(p);
      for (size_t k = 0; k < tris.size(); ++k)
        if (boxes_meet(pb, boxes[k]))
          if (Piece q = clip_triangle(p, tris[k]); !q.empty()) out.push_back(std::move(q));
    }
    return out;
  }

  MethodFeature begin(uint32_t rgba, bool line, uint32_t layer) const {
    MethodFeature f;
    f.rgba = rgba;
    f.line = line;
    f.layer = layer;
    f.first_triangle = uint32_t(out_.triangles.size() / 3);
    f.first_edge = uint32_t(out_.edges.size());
    f.box = {INFINITY, INFINITY, -INFINITY, -INFINITY};
    return f;
  }
  void add_triangle(MethodFeature& f, const std::array<P2d, 3>& t) {
    std::array<P2d, 3> c = t;
    if (cross(c[1] - c[0], c[2] - c[0]) < 0) std::swap(c[1], c[2]);
    for (const P2d& p : c) {
      out_.triangles.push_back(p);
      f.box.xmin = std::min(f.box.xmin, p[0]);
      f.box.ymin = std::min(f.box.ymin, p[1]);
      f.box.xmax = std::max(f.box.xmax, p[0]);
      f.box.ymax = std::max(f.box.ymax, p[1]);
    }
  }
  // A convex piece as a region of its own: a fan and all its edges.
  void add_piece(MethodFeature& f, Piece p) {
    p = ccw(std::move(p));
    if (p.size() < 3) return;
    for (size_t k = 1; k + 1 < p.size(); ++k) add_triangle(f, {p[0], p[k], p[k + 1]});
    for (size_t k = 0; k < p.size(); ++k) out_.edges.push_back({p[k], p[(k + 1) % p.size()]});
  }
  void finish(MethodFeature& f) {
    f.triangles = uint32_t(out_.triangles.size() / 3) - f.first_triangle;
    f.edges = uint32_t(out_.edges.size()) - f.first_edge;
    if (f.triangles > 0) out_.features.push_back(f);
  }

  const StaticView& v_;
  const std::optional<Extent>& clip_;
  MethodGeometry out_;
};

}  // namespace

MethodGeometry method_geometry(const StaticView& view, bool polygons, bool lines,
                               const std::optional<Extent>& clip) {
  Builder b(view, clip);
  if (polygons) {
    std::map<uint32_t, std::vector<uint32_t>> holes;
    for (uint32_t p = 0; p < view.poly_props.size(); ++p)
      if (view.poly_props[p].exterior >= 0)
        holes[uint32_t(view.poly_props[p].exterior)].push_back(p);
    for (uint32_t p = 0; p < view.poly_props.size(); ++p)
      if (view.poly_props[p].exterior < 0) b.polygon(p, holes[p]);
  }
  if (lines && !view.line_props.empty()) {
    std::vector<std::vector<uvec2>> per_line(view.line_props.size());
    for (const uvec2& s : view.cell_segments) {
      if (s[0] >= view.line_vertex_line.size()) continue;
      const uint32_t l = view.line_vertex_line[s[0]];
      if (l < per_line.size()) per_line[l].push_back(s);
    }
    for (uint32_t l = 0; l < per_line.size(); ++l)
      if (!per_line[l].empty()) b.line(l, per_line[l]);
  }
  MethodGeometry g = b.take();
  // Drawing order, top first; a line before a polygon of the same rank
  // (evaluator step 4).
  std::stable_sort(g.features.begin(), g.features.end(),
                   [](const MethodFeature& x, const MethodFeature& y) {
                     return x.rank != y.rank ? x.rank < y.rank : x.line && !y.line;
                   });
  return g;
}

}  // namespace prep::render::detail
