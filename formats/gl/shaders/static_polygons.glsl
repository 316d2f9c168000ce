// static_polygons.glsl — fragment shader of the static polygon pass
// (thesis Algorithm 3.5 and §4.4.1 "Polygons"), with decal_blobs.glsl
// (DECAL_POLYGONS) and static_common.glsl. Mirrors prep::evaluate():
// grid cell -> stack-less BVH over the cell's exterior polygons in drawing
// order -> quad-tree descent from the (cell, polygon) culling node -> leaf
// test (outside / inside / even-odd over the leaf polygon) -> the cell's
// interior polygons of that exterior cut it out (nested islands inside
// holes are exterior polygons themselves) -> front-to-back compositing,
// early exit. The numbered steps of the query block at the top of
// libprep/evaluate/evaluate.cpp are the specification.
// One pass draws the exterior polygons of ranks [u_order_lo, u_order_hi),
// one run of the drawing order (formats/SPEC.md "Drawing order"); leaves are
// in rank order, so the walk stops at the first rank past the run.
// Output: premultiplied colour of the run at this pixel, blended under what
// the passes of earlier (higher) runs drew.

layout(location = 0) out vec4 o_color;
#ifdef DECAL_UNLIT_LAYERS
layout(location = 1) out vec4 o_unlit;  // the unlit layers' share (static_common.glsl g_unlit)
#endif
uniform uint u_order_lo;
uniform uint u_order_hi;

// Exterior polygon entry (polygon, culling node, first hole, hole count).
// Step 7: a point in any of the cell's holes of this polygon is outside
// (islands inside holes are exterior polygons of their own).
bool polygon_covers(uvec4 e, vec2 p) {
  if (!qt_contains(e.y, p)) return false;
  for (uint h = e.z; h < e.z + e.w; ++h)
    if (qt_contains(cell_hole(h).y, p)) return false;
  return true;
}

#ifdef DECAL_AA_COVERAGE
// Signed distance of p to the boundary of the box (lo, hi), positive inside.
float inside_distance(vec2 lo, vec2 hi, vec2 p) {
  vec2 q = clamp(p, lo, hi);
  float out_d = length(p - q);
  if (out_d > 0.0) return -out_d;
  return min(min(p.x - lo.x, hi.x - p.x), min(p.y - lo.y, hi.y - p.y));
}

// Does segment a-b meet the closed box [lo, hi]? (Liang-Barsky.)
bool segment_meets_box(vec2 a, vec2 b, vec2 lo, vec2 hi) {
  vec2 d = b - a;
  float t0 = 0.0, t1 = 1.0;
  for (int k = 0; k < 2; ++k) {
    if (d[k] == 0.0) {
      if (a[k] < lo[k] || a[k] > hi[k]) return false;
      continue;
    }
    float ta = (lo[k] - a[k]) / d[k], tb = (hi[k] - a[k]) / d[k];
    t0 = max(t0, min(ta, tb));
    t1 = min(t1, max(ta, tb));
  }
  return t0 <= t1;
}

// Coverage AA (Thöny et al. §3.5 applied to polygon edges): the fraction of
// the pixel inside polygon `poly`, from the signed distance to its nearest
// edge, clamp(0.5 + sd / wpix). Edges: the ring edges of a partial leaf,
// and the polygon's bounding box (a point inside the polygon is at least as
// near the boundary as the box). A leaf polygon is its ring's edges that
// meet the leaf box, closed by segments that never do (formats/SPEC.md
// "Quad-tree nodes"; libprep/model/quadtree.cpp: from each chain end
// straight away from the box to a frame outside the polygon's box, then
// along it): those are skipped, as they lie in empty ground, where they drew
// lines one pixel wide along which the polygon's box and its chain ends
// seemed to be edges.
// A pixel whose point lies outside the entry's node box (within half a
// pixel of it) is outside the polygon: the node holds all of the polygon
// in the pixel's cell. It takes the leaf beside it (the point clamped into
// the box): a full leaf, or a partial one whose region holds the clamped
// point, puts the polygon at the clamped point; else the leaf's ring edges
// give the distance. The bounding box says nothing there.
float qt_coverage(uint poly, uint node, vec2 p, float wpix) {
  ivec4 rootq = qt_node_box(poly_root(poly));
  vec2 blo = rel(rootq.xy), bhi = rel(rootq.zw);
  ivec4 nb = qt_node_box(node);
  vec2 pc = clamp(p, rel(nb.xy), rel(nb.zw));
  float beside = length(p - pc);
  if (beside > 0.5 * wpix) return 0.0;
  bool outside_node = beside > 0.0;
  // The point whose side of the leaf's region counts: p, or the clamped
  // point a millimetre into the box.
  vec2 q = outside_node ? pc + (pc - p) * (1e-3 / beside) : p;
  float sd_box = inside_distance(blo, bhi, p);
  for (;;) {
    ivec2 n = qt_node(node);
    if (n.x == 0) {
      uint c = uint(n.y);
      uint next = 0xffffffffu;
      for (uint k = 0u; k < 4u; ++k) {
        if (box_contains(qt_node_box(c + k), pc)) { next = c + k; break; }
      }
      if (next == 0xffffffffu) return 0.0;
      node = next;
      continue;
    }
    if (n.x == 1) return 0.0;
    if (n.x == 2) return clamp(0.5 + (outside_node ? -beside : sd_box) / wpix, 0.0, 1.0);
    ivec4 lb = qt_node_box(node);
    vec2 llo = rel(lb.xy), lhi = rel(lb.zw);
    uvec2 r = qt_leaf_loop_range(uint(n.y));
    bool inside = false;
    float dist = 1e30;
    for (uint l = r.x; l < r.x + r.y; ++l) {
     uint s0 = qt_leaf_loop_start(l), s1 = qt_leaf_loop_end(l);
     for (uint s = s0; s < s1; ++s) {
      uvec2 e = uvec2(s, s + 1u < s1 ? s + 1u : s0);
      ivec2 ua = qt_leaf_vertex(e.x), ub = qt_leaf_vertex(e.y);
      vec2 Aq = rel(ua) - q, Bq = rel(ub) - q;
      if ((Aq.y > 0.0) != (Bq.y > 0.0)) {
        vec2 L = Aq.y > 0.0 ? Bq : Aq, H = Aq.y > 0.0 ? Aq : Bq;
        if ((H.x - L.x) * (-L.y) - (H.y - L.y) * (-L.x) > 0.0) inside = !inside;
      }
      if (!segment_meets_box(rel(ua), rel(ub), llo, lhi)) continue;  // a closing segment
      vec2 A = rel(ua) - p, B = rel(ub) - p;
      vec2 ab = B - A;
      float t = clamp(dot(-A, ab) / max(dot(ab, ab), 1e-20), 0.0, 1.0);
      dist = min(dist, length(A + t * ab));
     }
    }
    float sd = outside_node ? -(inside ? beside : dist) : min(inside ? dist : -dist, sd_box);
    return clamp(0.5 + sd / wpix, 0.0, 1.0);
  }
}

float polygon_coverage(uvec4 e, vec2 p, float wpix) {
  float c = qt_coverage(e.x, e.y, p, wpix);
  if (c <= 0.0) return 0.0;
  float h = 0.0;
  for (uint j = e.z; j < e.z + e.w; ++j) {
    uvec2 hole = cell_hole(j);
    h = max(h, qt_coverage(hole.x, hole.y, p, wpix));
  }
  return c * (1.0 - h);
}
#endif


ivec4 bvh_box(uint node, ivec3 base) { return poly_bvh_box(node, base); }

// Leaf of the walk (static_common.glsl bvh_walk): exterior polygon entry
// `entry` of the cell; false ends the walk (past the run, or opaque).
bool bvh_leaf(uint entry, vec2 p) {
  uvec4 e = cell_poly(entry);
  uint order = poly_order(e.x);
  if (order >= u_order_hi) return false;
  if (order < u_order_lo) return true;
#ifdef DECAL_AA_COVERAGE
  float cov = polygon_coverage(e, p, g_wpix);
  if (cov > 0.0 && under_opaque_cov(poly_rgba(e.x), cov, poly_layer(e.x))) return false;
#else
  if (polygon_covers(e, p) && under_opaque(poly_rgba(e.x), poly_layer(e.x))) return false;
#endif
  return true;
}

void main() {
  vec3 p;
  int cell;
  if (!pixel_cell(p, cell)) discard;
#ifdef DECAL_AA_COVERAGE
  float margin = 0.5 * g_wpix;
#else
  float margin = 0.0;
#endif
  bvh_walk(cell_poly_range(uint(cell)), poly_bvh_range(uint(cell)), cell_box_base(cell), p.xy,
           margin);
  if (g_acc.a <= 0.0) discard;
  o_color = g_acc;
#ifdef DECAL_UNLIT_LAYERS
  o_unlit = vec4(g_unlit, g_acc.a);
#endif
}
